#pragma once
// Replays a recorded session through acquisition's interfaces, exactly as the hardware
// sources deliver: a FrameSource for the frames (Mono16, device clock = recorded
// timestamps, sequence numbers) and a CArmGeometrySource for the C-arm states, merged on
// one timeline by one thread. In real time (original timestamps, or scaled by `speed`) or
// as fast as possible, optionally looping (device timestamps and sequence numbers keep
// increasing across loops, as a camera's would).
//
// Start the C-arm source first: the replay clock starts with the frame source, and
// C-arm states are delivered to a geometry source only once it has been started. Starting
// the frame source again restarts the replay. Callbacks run on the replay thread; they may
// query the sources but must not start or stop them (std::logic_error). No callback runs
// after a source's stop() returns.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>

#include "evar/acquisition/carm_geometry_source.hpp"
#include "evar/acquisition/frame_source.hpp"
#include "evar/session/session.hpp"

namespace evar::session {

/// Time for the replay, so tests can check the pacing without waiting.
class ReplayClock {
 public:
  using time_point = std::chrono::steady_clock::time_point;
  virtual ~ReplayClock() = default;
  virtual time_point now() = 0;
  /// Returns at `t` or when `cancelled` becomes true (checked at least every 50 ms).
  virtual void sleep_until(time_point t, const std::atomic<bool>& cancelled) = 0;
};

/// The steady clock.
std::shared_ptr<ReplayClock> steady_replay_clock();

/// The paced speeds a replay takes (besides 0, as fast as possible).
inline constexpr double kMinReplaySpeed = 0.01, kMaxReplaySpeed = 1000.0;

struct ReplayOptions {
  double speed = 1.0;  ///< 1 = real time, 2 = twice as fast (kMinReplaySpeed to kMaxReplaySpeed); 0 = as fast as possible
  int loops = 1;       ///< times through the session; 0 = until stopped
  /// Decode every frame before the first is played and keep them in memory (frames x
  /// width x height x 2 bytes), so each is delivered on time and the decoding does not
  /// compete with what receives them: a grabber does not decode PNG. Otherwise each frame
  /// is read when it is due.
  bool preload = false;
};

/// Memory that `preload` needs for a session (bytes).
std::uint64_t preload_bytes(const Session& session);

struct ReplayProgress {
  std::size_t frames = 0, carm_states = 0;  ///< delivered so far (all loops)
  std::size_t frames_per_loop = 0;
  std::int64_t loop = 0;                    ///< 0-based
  bool finished = false;
};

class SessionReplay {
 public:
  /// Throws std::invalid_argument for a speed other than 0 or kMinReplaySpeed to
  /// kMaxReplaySpeed, a negative loop count, or a timestamp outside the format's range
  /// (0 to kMaxTimestampNs). Looping forever ends with an error() once device times would
  /// pass 2^63 ns, instead of wrapping.
  SessionReplay(Session session, ReplayOptions options, std::shared_ptr<ReplayClock> clock = steady_replay_clock());
  ~SessionReplay();
  SessionReplay(const SessionReplay&) = delete;
  SessionReplay& operator=(const SessionReplay&) = delete;

  acquisition::FrameSource& frames();
  acquisition::CArmGeometrySource& carm();

  /// Blocks until the replay ends (all loops done, stopped, or a frame failed to load);
  /// false on timeout.
  bool wait(std::chrono::milliseconds timeout = std::chrono::milliseconds::max());
  ReplayProgress progress() const;
  /// The error that ended the replay early ("" when none), e.g. an unreadable frame file.
  std::string error() const;

 private:
  class Frames;
  class CArm;
  void run();
  void start_engine();
  void stop_engine();
  void refuse_from_replay_thread(const char* what) const;

  Session session_;
  ReplayOptions options_;
  std::shared_ptr<ReplayClock> clock_;
  std::unique_ptr<Frames> frames_;
  std::unique_ptr<CArm> carm_;
  std::mutex control_;  // start/stop of the replay thread
  std::thread thread_;
  std::atomic<std::thread::id> replay_thread_id_{};
  std::atomic<bool> cancel_{false};
  mutable std::mutex mutex_;
  std::condition_variable done_cv_;
  ReplayProgress progress_;
  std::string error_;
  bool running_ = false;
};

/// A frame's image as a grabbed frame: Mono16, little-endian rows, no padding.
acquisition::Frame to_frame(const cv::Mat& image16, std::uint64_t sequence, std::int64_t device_time_ns);

/// A C-arm sample as a C-arm state (device time shifted by `offset_ns`).
acquisition::CArmState to_carm_state(const CArmSample& sample, std::int64_t offset_ns);

}  // namespace evar::session
