#pragma once
// Records what a frame source and a C-arm geometry source deliver as a session
// (docs/SESSION_FORMAT.md) that `evarnode replay` and every reader of the format take: the
// frames as 16-bit PNG written by a writer thread as they come (Mono8 scaled by 257, Mono12
// by 16, so grey levels keep their meaning), the C-arm states on the frames' clock (the
// C-arm's own clock mapped onto the host's through a minimum-delay offset estimate), the
// patient scene copied in, and a JSON report of what arrived and what was lost.
#include <Eigen/Core>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "evar/acquisition/carm_geometry_source.hpp"
#include "evar/acquisition/frame_source.hpp"
#include "evar/sim/session.hpp"

namespace evar::sim {

struct RecorderOptions {
  std::filesystem::path out;                  ///< the session directory; must not exist or be empty
  std::filesystem::path scene;                ///< the patient's scene.json, copied into out/patient/
  Eigen::Matrix4d ct_to_carm = Eigen::Matrix4d::Identity();  ///< the registration at table 0
  double pixel_spacing_mm = 0.0;              ///< at the detector (square pixels)
  std::optional<double> device_thickness_mm;  ///< default: the scene's
  std::string source = "fluoro";              ///< frames/index.csv source column
  std::size_t max_queued_frames = 64;         ///< waiting for the disk; beyond, frames are not recorded
};

struct RecorderStatistics {
  std::uint64_t frames_received = 0, frames_written = 0;
  std::uint64_t frames_not_recorded = 0;  ///< the disk fell behind (queue full)
  std::uint64_t frames_refused = 0;       ///< a size other than the first frame's
  std::uint64_t carm_samples = 0;
  acquisition::StreamState video = acquisition::StreamState::Stopped, carm = acquisition::StreamState::Stopped;
  std::string video_reason, carm_reason;  ///< the sources' last words
  std::string last_error;                 ///< the last frame that could not be written, named
  double seconds = 0.0;                   ///< since start()
};

class SessionRecorder {
 public:
  /// Checks the options and loads the scene (geometry::InputError naming the file); the
  /// sources are only borrowed and must outlive the recorder.
  SessionRecorder(RecorderOptions options, acquisition::FrameSource& frames, acquisition::CArmGeometrySource& carm);
  ~SessionRecorder();
  SessionRecorder(const SessionRecorder&) = delete;
  SessionRecorder& operator=(const SessionRecorder&) = delete;

  /// Starts both sources and the writer.
  void start();
  RecorderStatistics statistics() const;
  /// Stops the sources, writes what is queued and the session files and report
  /// (out/record_report.json). Throws std::runtime_error when no frame arrived (the
  /// directory then holds the report and the copied scene) or no C-arm sample did (the
  /// session is written with its frames and no geometry, so nothing recorded is lost).
  Session finish();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// C-arm states on the host's steady clock: per sample, C-arm time plus the smallest
/// arrival delay among the samples within ±30 s of C-arm time around it; a clock that goes
/// back or jumps ahead by more than a second starts a new stretch. Timestamps never decrease.
std::vector<CArmSample> carm_on_host_clock(const std::vector<acquisition::CArmState>& states);

/// A grabbed frame as the session's 16-bit image (Mono8 ×257, Mono12 ×16, Mono16 as is).
cv::Mat to_session_image(const acquisition::Frame& frame);

}  // namespace evar::sim
