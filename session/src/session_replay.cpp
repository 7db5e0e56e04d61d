#include "evar/session/session_replay.hpp"

#include <algorithm>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "evar/acquisition/sequence_tracker.hpp"
#include "evar/acquisition/stream_state_reporter.hpp"

namespace evar::session {

namespace {

class SteadyClock final : public ReplayClock {
 public:
  time_point now() override { return std::chrono::steady_clock::now(); }
  void sleep_until(time_point t, const std::atomic<bool>& cancelled) override {
    while (!cancelled.load()) {
      const auto left = t - std::chrono::steady_clock::now();
      if (left <= std::chrono::steady_clock::duration::zero()) return;
      std::this_thread::sleep_for(std::min<std::chrono::steady_clock::duration>(left, std::chrono::milliseconds(50)));
    }
  }
};

}  // namespace

std::shared_ptr<ReplayClock> steady_replay_clock() { return std::make_shared<SteadyClock>(); }

acquisition::Frame to_frame(const cv::Mat& image, std::uint64_t sequence, std::int64_t device_time_ns) {
  if (image.type() != CV_16UC1) throw std::invalid_argument("to_frame: expected a 16-bit single-channel image");
  acquisition::Frame f;
  f.format = acquisition::PixelFormat::Mono16;
  f.width = image.cols;
  f.height = image.rows;
  f.stride_bytes = 2 * image.cols;
  f.pixels.resize(static_cast<std::size_t>(f.stride_bytes) * static_cast<std::size_t>(f.height));
  for (int r = 0; r < image.rows; ++r) {
    const std::uint16_t* row = image.ptr<std::uint16_t>(r);
    std::uint8_t* out = f.pixels.data() + static_cast<std::size_t>(r) * static_cast<std::size_t>(f.stride_bytes);
    for (int c = 0; c < image.cols; ++c) {  // little-endian words, whatever the host
      out[2 * c] = static_cast<std::uint8_t>(row[c] & 0xff);
      out[2 * c + 1] = static_cast<std::uint8_t>(row[c] >> 8);
    }
  }
  f.sequence = sequence;
  f.device_time_ns = device_time_ns;
  f.host_arrival = std::chrono::steady_clock::now();
  f.device_time_on_host = f.host_arrival;  // the replay clock is the recording's, delivered on time
  return f;
}

acquisition::CArmState to_carm_state(const CArmSample& c, std::int64_t offset_ns) {
  acquisition::CArmState s;
  static_cast<acquisition::CArmPose&>(s) = c;
  s.device_time_ns = c.timestamp_ns + offset_ns;
  s.host_arrival = std::chrono::steady_clock::now();
  return s;
}

// Callbacks run on the replay thread only, under the facade's delivery mutex (never under
// the state mutex, so a callback may ask state() or statistics()). stop() takes the
// delivery mutex, so no callback runs after it returns; calling start() or stop() from a
// callback (the replay thread) is refused with std::logic_error instead of deadlocking.

class SessionReplay::CArm final : public acquisition::CArmGeometrySource {
 public:
  explicit CArm(SessionReplay& owner) : owner_(owner) {}
  // A recording carries no line to be noisy and no C-arm status: no notices.
  void start(StateCallback on_state, StreamCallback on_stream, NoticeCallback) override {
    owner_.refuse_from_replay_thread("start");
    std::lock_guard delivery(delivery_);
    on_state_ = std::move(on_state);
    status_.listen(std::move(on_stream));
    status_.set(acquisition::StreamState::Streaming, "replaying the C-arm stream of " + owner_.session_.directory.string());
  }
  void stop() override {
    owner_.refuse_from_replay_thread("stop");
    std::lock_guard delivery(delivery_);
    on_state_ = nullptr;
    status_.clear();
  }
  acquisition::StreamState state() const override { return status_.state(); }
  std::string description() const override { return "replay C-arm " + owner_.session_.directory.string(); }

  void deliver(const acquisition::CArmState& s) {
    std::lock_guard delivery(delivery_);
    if (on_state_ && status_.state() == acquisition::StreamState::Streaming) on_state_(s);
  }
  /// The replay ended: a started stream says so (and delivers nothing more).
  void end(const std::string& reason) {
    std::lock_guard delivery(delivery_);
    if (status_.state() == acquisition::StreamState::Streaming) status_.set(acquisition::StreamState::Stopped, reason);
  }
  /// The frame source started a new replay: a started stream is live again.
  void restart() {
    std::lock_guard delivery(delivery_);
    if (on_state_ && status_.state() != acquisition::StreamState::Streaming)
      status_.set(acquisition::StreamState::Streaming, "replaying again");
  }

 private:
  SessionReplay& owner_;
  std::mutex delivery_;
  StateCallback on_state_;
  acquisition::StreamStateReporter status_;  // changed under the facade's delivery mutex: callbacks in order
};

class SessionReplay::Frames final : public acquisition::FrameSource {
 public:
  explicit Frames(SessionReplay& owner) : owner_(owner) {}
  void start(FrameCallback on_frame, StateCallback on_state) override {
    owner_.refuse_from_replay_thread("start");
    owner_.stop_engine();  // a running replay ends before the new one is set up
    {
      std::lock_guard delivery(delivery_);
      on_frame_ = std::move(on_frame);
      status_.listen(std::move(on_state));
      std::lock_guard lock(stats_mutex_);
      tracker_.reset();
    }
    set_state(acquisition::StreamState::Connecting, "opening " + owner_.session_.directory.string());
    set_state(acquisition::StreamState::Streaming, "replaying");
    owner_.carm_->restart();
    owner_.start_engine();
  }
  void stop() override {
    owner_.refuse_from_replay_thread("stop");
    owner_.stop_engine();
    std::lock_guard delivery(delivery_);
    on_frame_ = nullptr;
    status_.clear();
  }
  acquisition::StreamState state() const override { return status_.state(); }
  acquisition::SequenceStats statistics() const override {
    std::lock_guard lock(stats_mutex_);
    return tracker_.stats();
  }
  std::string description() const override { return "replay " + owner_.session_.directory.string(); }

  void deliver(const acquisition::Frame& f) {
    std::lock_guard delivery(delivery_);
    {
      std::lock_guard lock(stats_mutex_);
      tracker_.observe(f.sequence);
    }
    if (on_frame_) on_frame_(f);
  }
  void set_state(acquisition::StreamState s, const std::string& reason) {
    std::lock_guard delivery(delivery_);
    status_.set(s, reason);
  }

 private:
  SessionReplay& owner_;
  std::mutex delivery_;
  FrameCallback on_frame_;
  acquisition::StreamStateReporter status_;  // changed under the facade's delivery mutex: callbacks in order
  mutable std::mutex stats_mutex_;
  acquisition::SequenceTracker tracker_;
};

SessionReplay::SessionReplay(Session session, ReplayOptions options, std::shared_ptr<ReplayClock> clock)
    : session_(std::move(session)), options_(options), clock_(std::move(clock)) {
  if (!(options_.speed == 0.0 || (options_.speed >= kMinReplaySpeed && options_.speed <= kMaxReplaySpeed)) ||
      options_.loops < 0)
    throw std::invalid_argument("SessionReplay: speed must be 0.01 to 1000 (or 0 = as fast as possible) and loops >= 0 (0 = forever)");
  // The loop arithmetic below relies on the format's timestamp range; a session built in
  // memory has not been through read_session.
  const auto check_time = [](std::int64_t t, const char* what) {
    if (t < 0 || t >= kMaxTimestampNs)
      throw std::invalid_argument(std::string("SessionReplay: a ") + what + " timestamp of " + std::to_string(t) +
                                  " ns is outside 0 to 2^62");
  };
  for (const auto& f : session_.frames) check_time(f.timestamp_ns, "frame");
  for (const auto& c : session_.carm) check_time(c.timestamp_ns, "C-arm");
  if (!clock_) throw std::invalid_argument("SessionReplay: no clock");
  frames_ = std::make_unique<Frames>(*this);
  carm_ = std::make_unique<CArm>(*this);
  progress_.frames_per_loop = session_.frames.size();
}

SessionReplay::~SessionReplay() { stop_engine(); }

acquisition::FrameSource& SessionReplay::frames() { return *frames_; }
acquisition::CArmGeometrySource& SessionReplay::carm() { return *carm_; }

void SessionReplay::refuse_from_replay_thread(const char* what) const {
  if (std::this_thread::get_id() == replay_thread_id_.load())
    throw std::logic_error(std::string("SessionReplay: ") + what + "() called from a replay callback");
}

void SessionReplay::start_engine() {
  std::lock_guard control(control_);
  std::lock_guard lock(mutex_);
  cancel_ = false;
  progress_ = ReplayProgress{};
  progress_.frames_per_loop = session_.frames.size();
  error_.clear();
  running_ = true;
  thread_ = std::thread([this] {
    replay_thread_id_ = std::this_thread::get_id();
    run();
  });
}

void SessionReplay::stop_engine() {
  std::lock_guard control(control_);
  cancel_ = true;
  if (thread_.joinable()) thread_.join();
  replay_thread_id_ = std::thread::id();
}

bool SessionReplay::wait(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  if (timeout == std::chrono::milliseconds::max()) {
    done_cv_.wait(lock, [&] { return !running_; });
    return true;
  }
  return done_cv_.wait_for(lock, timeout, [&] { return !running_; });
}

ReplayProgress SessionReplay::progress() const {
  std::lock_guard lock(mutex_);
  return progress_;
}

std::string SessionReplay::error() const {
  std::lock_guard lock(mutex_);
  return error_;
}

std::uint64_t preload_bytes(const Session& session) {
  const auto [cols, rows] = frame_size_px(session);
  return static_cast<std::uint64_t>(session.frames.size()) * static_cast<std::uint64_t>(cols) *
         static_cast<std::uint64_t>(rows) * 2u;
}

void SessionReplay::run() {
  // One timeline: C-arm samples before frames at the same time (the geometry in force).
  struct Event {
    std::int64_t t;
    bool frame;
    std::size_t index;
  };
  std::vector<Event> events;
  for (std::size_t i = 0; i < session_.carm.size(); ++i) events.push_back({session_.carm[i].timestamp_ns, false, i});
  for (std::size_t i = 0; i < session_.frames.size(); ++i) events.push_back({session_.frames[i].timestamp_ns, true, i});
  std::stable_sort(events.begin(), events.end(), [](const Event& a, const Event& b) {
    return a.t < b.t || (a.t == b.t && !a.frame && b.frame);
  });
  std::string reason = "end of session";
  std::vector<acquisition::Frame> decoded;  // with preload: every frame, before the first is played
  if (options_.preload) {
    try {
      decoded.reserve(session_.frames.size());
      for (std::size_t i = 0; i < session_.frames.size() && !cancel_; ++i)
        decoded.push_back(to_frame(read_session_frame(session_, i), 0, 0));
    } catch (const std::exception& ex) {
      std::lock_guard lock(mutex_);
      error_ = ex.what();
      events.clear();
    }
  }
  // A callback that throws ends the replay with its message (nothing escapes the thread).
  const auto deliver = [&](auto&& call) {
    try {
      call();
      return true;
    } catch (const std::exception& ex) {
      std::lock_guard lock(mutex_);
      error_ = std::string("a frame or C-arm callback threw: ") + ex.what();
      return false;
    }
  };
  if (!events.empty()) {
    const std::int64_t t0 = events.front().t;
    // A loop lasts the session plus one typical frame interval, so timestamps keep rising.
    std::int64_t gap = 66'666'667;
    if (session_.frames.size() >= 2)
      gap = std::max<std::int64_t>(1, (session_.frames.back().timestamp_ns - session_.frames.front().timestamp_ns) /
                                          static_cast<std::int64_t>(session_.frames.size() - 1));
    // Timestamps are below 2^62 (checked on construction), so span, gap and period fit.
    const std::int64_t period = events.back().t - t0 + gap;
    // The largest offset for which every device time (t + offset) stays below 2^63.
    const std::int64_t last_offset = std::numeric_limits<std::int64_t>::max() - kMaxTimestampNs;
    // No wait is longer than this (about 31 years), so a due time never overflows the clock.
    constexpr double kLongestWaitNs = 1e18;
    const auto start = clock_->now();
    std::uint64_t sequence = 0;
    for (std::int64_t loop = 0; options_.loops == 0 || loop < options_.loops; ++loop) {
      if (loop > last_offset / period) {
        std::lock_guard lock(mutex_);
        error_ = "device time would pass 2^63 ns after " + std::to_string(loop) + " loops; the replay stops here";
        break;
      }
      {
        std::lock_guard lock(mutex_);
        progress_.loop = loop;
      }
      const std::int64_t offset = loop * period;
      for (const Event& e : events) {
        if (cancel_) break;
        if (options_.speed > 0.0) {
          const double wait_ns = std::min(static_cast<double>(e.t + offset - t0) / options_.speed, kLongestWaitNs);
          const auto due = start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                       std::chrono::duration<double, std::nano>(wait_ns));
          clock_->sleep_until(due, cancel_);
          if (cancel_) break;
        }
        if (e.frame) {
          acquisition::Frame f;
          try {
            if (options_.preload) {
              f = decoded[e.index];
              f.sequence = ++sequence;
              f.device_time_ns = e.t + offset;
              f.host_arrival = std::chrono::steady_clock::now();
              f.device_time_on_host = f.host_arrival;
            } else {
              f = to_frame(read_session_frame(session_, e.index), ++sequence, e.t + offset);
            }
          } catch (const std::exception& ex) {
            std::lock_guard lock(mutex_);
            error_ = ex.what();
            break;
          }
          if (!deliver([&] { frames_->deliver(f); })) break;
          std::lock_guard lock(mutex_);
          ++progress_.frames;
        } else {
          if (!deliver([&] { carm_->deliver(to_carm_state(session_.carm[e.index], offset)); })) break;
          std::lock_guard lock(mutex_);
          ++progress_.carm_states;
        }
      }
      if (cancel_ || !error().empty()) break;
    }
    if (cancel_) reason = "stopped";
  }
  const std::string failure = error();
  if (!failure.empty()) {
    frames_->set_state(acquisition::StreamState::Disconnected, failure);
    carm_->end(failure);
  } else {
    frames_->set_state(acquisition::StreamState::Stopped, reason);
    carm_->end(reason);
  }
  std::lock_guard lock(mutex_);
  progress_.finished = true;
  running_ = false;
  done_cv_.notify_all();
}

}  // namespace evar::session
