#include "evar/sim/session_recorder.hpp"

#include <algorithm>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <fstream>
#include <limits>
#include <mutex>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <thread>
#include <vector>

#include "evar/acquisition/clock_offset.hpp"
#include "evar/geometry/scene.hpp"

namespace evar::sim {

namespace fs = std::filesystem;
using acquisition::CArmState;
using acquisition::Frame;
using acquisition::PixelFormat;
using acquisition::StreamState;

cv::Mat to_session_image(const Frame& f) {
  if (f.width <= 0 || f.height <= 0) throw std::invalid_argument("frame has no size");
  const int bpp = acquisition::bytes_per_pixel(f.format);
  if (f.stride_bytes < f.width * bpp ||
      f.pixels.size() < static_cast<std::size_t>(f.stride_bytes) * static_cast<std::size_t>(f.height - 1) +
                            static_cast<std::size_t>(f.width * bpp))
    throw std::invalid_argument("frame of " + std::to_string(f.width) + "x" + std::to_string(f.height) + " holds only " +
                                std::to_string(f.pixels.size()) + " bytes");
  cv::Mat out(f.height, f.width, CV_16UC1);
  for (int y = 0; y < f.height; ++y) {
    const std::uint8_t* in = f.pixels.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(f.stride_bytes);
    auto* o = out.ptr<std::uint16_t>(y);
    for (int x = 0; x < f.width; ++x) {
      if (f.format == PixelFormat::Mono8) {
        o[x] = static_cast<std::uint16_t>(in[x] * 257);
      } else {
        const auto v = static_cast<std::uint16_t>(in[2 * x] | (in[2 * x + 1] << 8));  // little-endian words
        o[x] = f.format == PixelFormat::Mono12 ? static_cast<std::uint16_t>(std::min<int>(v, 4095) * 16) : v;
      }
    }
  }
  return out;
}

namespace {

std::int64_t ns_of(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
}

}  // namespace

std::vector<CArmSample> carm_on_host_clock(const std::vector<CArmState>& states) {
  std::vector<acquisition::ClockPair> pairs;
  pairs.reserve(states.size());
  for (const CArmState& s : states) pairs.push_back({s.device_time_ns, ns_of(s.host_arrival)});
  const std::vector<std::int64_t> host_ns = acquisition::device_times_on_host(pairs);
  std::vector<CArmSample> out;
  out.reserve(states.size());
  for (std::size_t i = 0; i < states.size(); ++i) {
    const CArmState& s = states[i];
    CArmSample c;
    c.timestamp_ns = host_ns[i];
    c.primary_deg = s.primary_deg;
    c.secondary_deg = s.secondary_deg;
    c.sid_mm = s.sid_mm;
    c.sod_mm = s.sod_mm;
    c.table_mm = {s.table_mm[0], s.table_mm[1], s.table_mm[2]};
    c.fluoro_on = s.fluoro_on;
    c.moving = s.moving;
    out.push_back(c);
  }
  return out;
}

namespace {

// Frames timed by a device clock were stamped live with the offset known so far; with the
// whole recording at hand, each gets the offset of the frames around it, later ones too.
// `frames` is in frame-number order and stays so.
void map_frames_offline(const std::vector<std::pair<std::int64_t, acquisition::ClockPair>>& device_clock_frames,
                        std::vector<FrameRecord>& frames) {
  if (device_clock_frames.empty()) return;
  std::vector<acquisition::ClockPair> pairs;
  pairs.reserve(device_clock_frames.size());
  for (const auto& [frame, pair] : device_clock_frames) pairs.push_back(pair);
  const std::vector<std::int64_t> host_ns = acquisition::device_times_on_host(pairs);
  std::size_t k = 0;
  std::int64_t last = std::numeric_limits<std::int64_t>::min();
  for (FrameRecord& r : frames) {
    while (k < device_clock_frames.size() && device_clock_frames[k].first < r.frame) ++k;
    if (k < device_clock_frames.size() && device_clock_frames[k].first == r.frame) r.timestamp_ns = host_ns[k];
    r.timestamp_ns = std::max(r.timestamp_ns, last);
    last = r.timestamp_ns;
  }
}

}  // namespace

struct SessionRecorder::Impl {
  RecorderOptions options;
  acquisition::FrameSource& frames;
  acquisition::CArmGeometrySource& carm;
  geometry::Scene scene;

  mutable std::mutex mutex;
  std::condition_variable wake;
  std::deque<std::pair<FrameRecord, Frame>> queue;
  bool closing = false;
  std::thread writer;
  std::chrono::steady_clock::time_point started;
  RecorderStatistics stats;
  std::optional<std::pair<int, int>> size;  // the first frame's (cols, rows)
  std::vector<FrameRecord> written;
  std::vector<CArmState> states;
  std::int64_t next_frame = 1;
  std::int64_t last_frame_ns = std::numeric_limits<std::int64_t>::min();
  // Frames whose time is a device clock: (frame number, clock sample), mapped again at finish.
  std::vector<std::pair<std::int64_t, acquisition::ClockPair>> device_clock_frames;

  Impl(RecorderOptions o, acquisition::FrameSource& f, acquisition::CArmGeometrySource& c)
      : options(std::move(o)), frames(f), carm(c) {}

  void on_frame(const Frame& f) {
    std::lock_guard lock(mutex);
    ++stats.frames_received;
    if (!size) size = std::make_pair(f.width, f.height);
    if (size->first != f.width || size->second != f.height) {
      ++stats.frames_refused;
      stats.last_error = "frame of " + std::to_string(f.width) + "x" + std::to_string(f.height) + " in a session of " +
                         std::to_string(size->first) + "x" + std::to_string(size->second) + " not recorded";
      return;
    }
    if (queue.size() >= options.max_queued_frames) {
      ++stats.frames_not_recorded;
      stats.last_error = "the disk fell behind: " + std::to_string(queue.size()) + " frames waiting";
      return;
    }
    FrameRecord r;
    r.frame = next_frame++;
    r.timestamp_ns = std::max(ns_of(f.device_time_on_host), last_frame_ns);
    last_frame_ns = r.timestamp_ns;
    r.source = options.source;
    if (f.device_clock) device_clock_frames.push_back({r.frame, {f.device_time_ns, ns_of(f.host_arrival)}});
    char name[32];
    std::snprintf(name, sizeof name, "f%07lld.png", static_cast<long long>(r.frame));
    r.file = name;
    queue.emplace_back(r, f);
    wake.notify_one();
  }

  void write_frames() {
    for (;;) {
      std::unique_lock lock(mutex);
      wake.wait(lock, [&] { return closing || !queue.empty(); });
      if (queue.empty()) return;
      auto [record, frame] = std::move(queue.front());
      queue.pop_front();
      lock.unlock();
      std::string error;
      try {
        write_session_frame(options.out, record, to_session_image(frame));
      } catch (const std::exception& e) {
        error = "frame " + std::to_string(record.frame) + ": " + e.what();
      }
      lock.lock();
      if (error.empty()) {
        written.push_back(record);
        ++stats.frames_written;
      } else {
        stats.last_error = error;
      }
    }
  }

  void write_report(const Session* session) const {
    const RecorderStatistics s = stats;
    const acquisition::SequenceStats source = frames.statistics();
    nlohmann::ordered_json j = {
        {"format", "evarnode-record-report"},
        {"version", 1},
        {"seconds", s.seconds},
        {"frames",
         {{"received", s.frames_received},
          {"written", s.frames_written},
          {"not_recorded_disk_behind", s.frames_not_recorded},
          {"refused_size_changed", s.frames_refused},
          {"source", frames.description()},
          {"statistics",
           {{"received", source.received}, {"dropped", source.dropped}, {"out_of_order", source.out_of_order}}},
          {"last_state", acquisition::to_string(s.video)},
          {"last_reason", s.video_reason}}},
        {"carm",
         {{"samples", s.carm_samples},
          {"source", carm.description()},
          {"last_state", acquisition::to_string(s.carm)},
          {"last_reason", s.carm_reason}}},
        {"last_error", s.last_error},
        {"session_written", session != nullptr}};
    if (session && !session->frames.empty())
      j["frames"]["span_s"] = 1e-9 * static_cast<double>(session->frames.back().timestamp_ns - session->frames.front().timestamp_ns);
    std::ofstream(options.out / "record_report.json") << j.dump(2) << "\n";
  }
};

SessionRecorder::SessionRecorder(RecorderOptions options, acquisition::FrameSource& frames,
                                 acquisition::CArmGeometrySource& carm) {
  if (options.out.empty()) throw std::invalid_argument("record: no output directory");
  if (fs::exists(options.out) && !(fs::is_directory(options.out) && fs::is_empty(options.out)))
    throw std::invalid_argument(options.out.string() + ": exists and is not an empty directory; choose a new session directory");
  if (!(options.pixel_spacing_mm > 0.0 && options.pixel_spacing_mm < 10.0))
    throw std::invalid_argument("record: the detector pixel spacing must be in (0, 10) mm");
  if (options.max_queued_frames < 1) throw std::invalid_argument("record: the frame queue needs room for a frame");
  impl_ = std::make_unique<Impl>(std::move(options), frames, carm);
  impl_->scene = geometry::load_scene(impl_->options.scene);
  if (impl_->options.device_thickness_mm && !(*impl_->options.device_thickness_mm >= 0.0 && *impl_->options.device_thickness_mm <= 15.0))
    throw std::invalid_argument("record: device thickness must be 0 to 15 mm");
}

SessionRecorder::~SessionRecorder() {
  if (impl_->writer.joinable()) {
    try {
      finish();
    } catch (...) {  // a destructor must not throw; finish() was the caller's to call
    }
  }
}

void SessionRecorder::start() {
  Impl& d = *impl_;
  if (d.writer.joinable()) throw std::logic_error("record: already started");
  fs::create_directories(d.options.out / "frames");
  geometry::copy_scene(d.scene, d.options.out / "patient");
  d.started = std::chrono::steady_clock::now();
  d.writer = std::thread([&d] { d.write_frames(); });
  d.carm.start(
      [&d](const CArmState& s) {
        std::lock_guard lock(d.mutex);
        d.states.push_back(s);
        ++d.stats.carm_samples;
      },
      [&d](StreamState s, const std::string& why) {
        std::lock_guard lock(d.mutex);
        d.stats.carm = s;
        d.stats.carm_reason = why;
      });
  d.frames.start([&d](const Frame& f) { d.on_frame(f); },
                 [&d](StreamState s, const std::string& why) {
                   std::lock_guard lock(d.mutex);
                   d.stats.video = s;
                   d.stats.video_reason = why;
                 });
}

RecorderStatistics SessionRecorder::statistics() const {
  std::lock_guard lock(impl_->mutex);
  RecorderStatistics s = impl_->stats;
  if (impl_->writer.joinable()) s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - impl_->started).count();
  return s;
}

Session SessionRecorder::finish() {
  Impl& d = *impl_;
  if (!d.writer.joinable()) throw std::logic_error("record: finish() without start()");
  d.frames.stop();  // no callback after these
  d.carm.stop();
  {
    std::lock_guard lock(d.mutex);
    d.closing = true;
    d.stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - d.started).count();
  }
  d.wake.notify_all();
  d.writer.join();

  Session s;
  s.directory = d.options.out;
  s.scene = "patient/scene.json";
  s.ct_to_carm = d.options.ct_to_carm;
  s.device_thickness_mm = d.options.device_thickness_mm.value_or(d.scene.device_thickness_mm);
  s.frames = d.written;
  map_frames_offline(d.device_clock_frames, s.frames);
  s.carm = carm_on_host_clock(d.states);
  if (d.size) s.detector = {d.size->first, d.size->second, d.options.pixel_spacing_mm, d.options.pixel_spacing_mm};
  if (s.frames.empty()) {
    d.write_report(nullptr);
    throw std::runtime_error("nothing was recorded: no frame arrived (video: " + d.stats.video_reason + "); see " +
                             (d.options.out / "record_report.json").string());
  }
  write_session_files(d.options.out, s);  // frames are kept even without geometry
  d.write_report(&s);
  if (s.carm.empty())
    throw std::runtime_error(std::to_string(s.frames.size()) + " frames were recorded but no C-arm sample (C-arm: " +
                             d.stats.carm_reason + "): " + d.options.out.string() +
                             " holds the frames without geometry; it replays, but cannot be deformed or overlaid");
  return s;
}

}  // namespace evar::sim
