#include "evar/session/session_recorder.hpp"

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

#include "recording_journal.hpp"
#include "evar/base/atomic_file.hpp"
#include "evar/geometry/scene.hpp"

namespace evar::session {

namespace fs = std::filesystem;
using acquisition::CArmState;
using acquisition::Frame;
using acquisition::PixelFormat;
using acquisition::StreamState;
using namespace recording;

cv::Mat to_session_image(const Frame& f) {
  acquisition::check_layout(f);
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

struct SessionRecorder::Impl {
  RecorderOptions options;
  acquisition::FrameSource& frames;
  acquisition::CArmGeometrySource& carm;
  geometry::Scene scene;
  RecordingSettings settings;

  mutable std::mutex mutex;
  std::condition_variable wake;
  std::deque<std::pair<FrameRecord, Frame>> queue;
  bool closing = false;
  std::thread writer;
  std::chrono::steady_clock::time_point started;
  RecorderStatistics stats;
  RecordedStreams streams;
  // The frames' size when the options fix it (a video mapping's, the zoom modes'), else the first frame's.
  std::optional<std::pair<int, int>> frame_size;
  std::int64_t next_frame = 1;
  std::int64_t last_frame_ns = std::numeric_limits<std::int64_t>::min();
  std::string carm_rows;  // C-arm journal rows not yet written
  // The writer thread's alone while it runs.
  std::ofstream journal_frames, journal_carm;
  bool journal_failed = false;

  Impl(RecorderOptions o, acquisition::FrameSource& f, acquisition::CArmGeometrySource& c)
      : options(std::move(o)), frames(f), carm(c) {}

  void on_frame(const Frame& f) {
    std::lock_guard lock(mutex);
    ++stats.frames_received;
    // Under a video mapping every frame has its video size; else the first frame's is the session's.
    if (!streams.size) streams.size = frame_size.value_or(std::make_pair(f.width, f.height));
    if (streams.size->first != f.width || streams.size->second != f.height) {
      ++stats.frames_refused;
      stats.last_error = "frame of " + std::to_string(f.width) + "x" + std::to_string(f.height) + " in a session of " +
                         std::to_string(streams.size->first) + "x" + std::to_string(streams.size->second) + " not recorded";
      return;
    }
    if (queue.size() >= options.max_queued_frames) {
      ++stats.frames_not_recorded;
      stats.last_error = "the disk fell behind: " + std::to_string(queue.size()) + " frames waiting";
      return;
    }
    FrameRecord r;
    r.timestamp_ns = std::max(ns_of(f.device_time_on_host), last_frame_ns);
    if (r.timestamp_ns < 0 || r.timestamp_ns >= kMaxTimestampNs) {
      // Refused here, before it raises every later frame's time out of range too.
      ++stats.frames_refused;
      stats.last_error = "frame not recorded: its time " + std::to_string(r.timestamp_ns) + " ns is outside 0 to 2^62";
      return;
    }
    r.frame = next_frame++;
    last_frame_ns = r.timestamp_ns;
    r.source = options.source;
    if (f.device_clock) streams.device_clock_frames.push_back({r.frame, {f.device_time_ns, ns_of(f.host_arrival)}});
    char name[32];
    std::snprintf(name, sizeof name, "f%07lld.png", static_cast<long long>(r.frame));
    r.file = name;
    queue.emplace_back(r, f);
    wake.notify_one();
  }

  // A state the format would refuse (an angle out of range, SOD >= SID, not finite) is
  // counted and left out: one bad sample must not cost the whole session.
  void on_carm(const CArmState& s) {
    const std::string problem = carm_sample_problem(sample_of(s, ns_of(s.host_arrival)));
    std::lock_guard lock(mutex);
    if (!problem.empty()) {
      ++stats.carm_refused;
      stats.last_error = "C-arm state not recorded: " + problem;
      return;
    }
    streams.states.push_back(s);
    ++stats.carm_samples;
    carm_rows += journal_carm_row(s);
  }

  void append(std::ofstream& journal, const std::string& rows) {
    journal << rows;
    journal.flush();  // into the kernel: a killed process loses nothing written
    if (!journal && !journal_failed) {
      journal_failed = true;
      std::lock_guard lock(mutex);
      stats.last_error = "cannot write the journal in " + journal_of(options.out).string() +
                         " (disk full?): a recording that does not finish cannot be recovered in full";
    }
  }

  void write_frame(const FrameRecord& record, const Frame& frame) {
    std::string error;
    try {
      write_session_frame(options.out, record, to_session_image(frame));
    } catch (const std::exception& e) {
      error = "frame " + std::to_string(record.frame) + ": " + e.what();
    }
    if (error.empty()) {
      // The C-arm states that came before this frame go into the journal first: a frame
      // recovered after a kill must not be paired with an older state than it was seen with
      // (the periodic flush alone left the last second's states out).
      std::string rows;
      {
        std::lock_guard lock(mutex);
        rows.swap(carm_rows);
      }
      if (!rows.empty()) append(journal_carm, rows);
      append(journal_frames, journal_frame_row(record, frame));  // its PNG is on disk
    }
    std::lock_guard lock(mutex);
    if (error.empty()) {
      streams.frames.push_back(record);
      ++stats.frames_written;
    } else {
      ++stats.frames_write_failed;
      stats.last_error = error;
    }
  }

  void flush_journal() {
    std::string rows;
    {
      std::lock_guard lock(mutex);
      rows.swap(carm_rows);
    }
    if (!rows.empty()) append(journal_carm, rows);
    try {
      write_report(snapshot(), nullptr, true);
    } catch (const std::exception& e) {
      std::lock_guard lock(mutex);
      stats.last_error = e.what();
    }
  }

  void write_frames() {
    auto next_flush = std::chrono::steady_clock::now() + kJournalPeriod;
    for (;;) {
      std::optional<std::pair<FrameRecord, Frame>> item;
      bool done = false;
      {
        std::unique_lock lock(mutex);
        wake.wait_until(lock, next_flush, [&] { return closing || !queue.empty(); });
        if (!queue.empty()) {
          item = std::move(queue.front());
          queue.pop_front();
        } else {
          done = closing;
        }
      }
      if (item) write_frame(item->first, item->second);
      if (done || std::chrono::steady_clock::now() >= next_flush) {
        flush_journal();
        next_flush = std::chrono::steady_clock::now() + kJournalPeriod;
      }
      if (done) return;
    }
  }

  RecorderStatistics snapshot() const {
    std::lock_guard lock(mutex);
    RecorderStatistics s = stats;
    if (!closing) s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    return s;
  }

  void write_report(const RecorderStatistics& s, const Session* session, bool in_progress) const {
    const acquisition::SequenceStats source = frames.statistics();
    nlohmann::ordered_json j = {
        {"format", "evarnode-record-report"},
        {"version", 1},
        {"in_progress", in_progress},
        {"seconds", s.seconds},
        {"frames",
         {{"received", s.frames_received},
          {"written", s.frames_written},
          {"not_recorded_disk_behind", s.frames_not_recorded},
          {"refused_size_changed", s.frames_refused},
          {"write_failed", s.frames_write_failed},
          {"source", frames.description()},
          {"statistics",
           {{"received", source.received}, {"dropped", source.dropped}, {"out_of_order", source.out_of_order}}},
          {"last_state", acquisition::to_string(s.video)},
          {"last_reason", s.video_reason}}},
        {"carm",
         {{"samples", s.carm_samples},
          {"refused_invalid", s.carm_refused},
          {"zoom_unlisted", s.carm_zoom_unlisted},
          {"source", carm.description()},
          {"last_state", acquisition::to_string(s.carm)},
          {"last_reason", s.carm_reason},
          {"notices", s.carm_notices},
          {"recent_notices", s.recent_carm_notices}}},
        {"last_error", s.last_error},
        {"session_written", session != nullptr}};
    if (session && !session->frames.empty())
      j["frames"]["span_s"] = 1e-9 * static_cast<double>(session->frames.back().timestamp_ns - session->frames.front().timestamp_ns);
    // In progress it is rewritten every second on the writer thread, which must not wait
    // for the disk; the last one is synced.
    write_json_file(options.out / "record_report.json", j, in_progress ? base::Durability::Deferred : base::Durability::Synced);
  }

  void start_journal() {
    const fs::path dir = journal_of(options.out);
    fs::create_directories(dir);
    nlohmann::ordered_json rows = nlohmann::ordered_json::array();
    for (int r = 0; r < 4; ++r)
      rows.push_back({settings.ct_to_carm(r, 0), settings.ct_to_carm(r, 1), settings.ct_to_carm(r, 2), settings.ct_to_carm(r, 3)});
    nlohmann::ordered_json j{{"format", kJournalFormat},
                             {"version", 1},
                             {"registration", rows},
                             {"device_thickness_mm", settings.device_thickness_mm},
                             {"pixel_spacing_mm", settings.pixel_spacing_mm}};
    if (settings.video_mapping)
      j["video_mapping"] = nlohmann::ordered_json::parse(geometry::video_mapping_json(*settings.video_mapping).dump());
    if (!settings.zoom_modes.empty())
      j["zoom_modes"] = nlohmann::ordered_json::parse(geometry::zoom_modes_json(settings.zoom_modes).dump());
    if (settings.zoom_mode != 0) j["zoom_mode"] = settings.zoom_mode;
    if (settings.video_mapping || !settings.zoom_modes.empty())
      j["detector_px"] = {settings.detector_px.first, settings.detector_px.second};
    write_json_file(dir / "recording.json", j);
    journal_frames.open(dir / "frames.csv", std::ios::binary | std::ios::trunc);
    journal_carm.open(dir / "carm.csv", std::ios::binary | std::ios::trunc);
    journal_frames << kJournalFramesHeader << "\n" << std::flush;
    journal_carm << kJournalCArmHeader << "\n" << std::flush;
    if (!journal_frames || !journal_carm) throw std::runtime_error(dir.string() + ": cannot write the recording journal");
  }
};

SessionRecorder::SessionRecorder(RecorderOptions options, acquisition::FrameSource& frames,
                                 acquisition::CArmGeometrySource& carm) {
  if (options.out.empty()) throw std::invalid_argument("record: no output directory");
  if (fs::exists(options.out) && !(fs::is_directory(options.out) && fs::is_empty(options.out)))
    throw std::invalid_argument(options.out.string() + ": exists and is not an empty directory; choose a new session directory" +
                                (fs::is_directory(journal_of(options.out))
                                     ? " (it holds an unfinished recording: `evarnode record --recover " + options.out.string() +
                                           "` makes a session of it)"
                                     : std::string()));
  if (!(options.pixel_spacing_mm > 0.0 && options.pixel_spacing_mm < 10.0))
    throw std::invalid_argument("record: the detector pixel spacing must be in (0, 10) mm");
  if (options.max_queued_frames < 1) throw std::invalid_argument("record: the frame queue needs room for a frame");
  impl_ = std::make_unique<Impl>(std::move(options), frames, carm);
  impl_->scene = geometry::load_scene(impl_->options.scene);
  if (impl_->options.device_thickness_mm && !(*impl_->options.device_thickness_mm >= 0.0 && *impl_->options.device_thickness_mm <= 15.0))
    throw std::invalid_argument("record: device thickness must be 0 to 15 mm");
  const auto [cols, rows] = impl_->options.detector_px;
  if (!impl_->options.zoom_modes.empty()) {
    // The session's own rules: each mode on the detector, fitting the mapping, one frame size.
    Session probe;
    probe.detector = {cols, rows, impl_->options.pixel_spacing_mm, impl_->options.pixel_spacing_mm};
    probe.video_mapping = impl_->options.video_mapping;
    probe.zoom_modes = impl_->options.zoom_modes;
    if (const auto problem = zoom_modes_problem(probe); !problem.empty())
      throw std::invalid_argument("record: " + problem + " (detector " + std::to_string(cols) + " x " + std::to_string(rows) + ")");
    if (impl_->options.zoom_mode != 0 && !geometry::find_zoom_mode(impl_->options.zoom_modes, impl_->options.zoom_mode))
      throw std::invalid_argument("record: zoom_mode " + std::to_string(impl_->options.zoom_mode) + " is not one of zoom_modes");
    impl_->frame_size = geometry::frame_size_px(impl_->options.video_mapping, impl_->options.zoom_modes.front());
  } else if (impl_->options.video_mapping) {
    if (const auto problem = geometry::video_mapping_fit_problem(*impl_->options.video_mapping, cols, rows); !problem.empty())
      throw std::invalid_argument("record: " + problem + " (detector " + std::to_string(cols) + " x " + std::to_string(rows) + ")");
    impl_->frame_size = std::make_pair(impl_->options.video_mapping->video_cols, impl_->options.video_mapping->video_rows);
  }
  impl_->settings = {impl_->options.ct_to_carm, impl_->options.device_thickness_mm.value_or(impl_->scene.device_thickness_mm),
                     impl_->options.pixel_spacing_mm, impl_->options.video_mapping, impl_->options.detector_px,
                     impl_->options.zoom_modes, impl_->options.zoom_mode};
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
  d.start_journal();
  d.started = std::chrono::steady_clock::now();
  d.writer = std::thread([&d] { d.write_frames(); });
  d.carm.start([&d](const CArmState& s) { d.on_carm(s); },
               [&d](StreamState s, const std::string& why) {
                 std::lock_guard lock(d.mutex);
                 d.stats.carm = s;
                 d.stats.carm_reason = why;
               },
               [&d](const acquisition::LinkNotice& notice) {
                 std::lock_guard lock(d.mutex);
                 auto& recent = d.stats.recent_carm_notices;
                 if (recent.size() == RecorderStatistics::kRecentNotices) recent.erase(recent.begin());
                 recent.push_back(notice.text);
                 ++d.stats.carm_notices;
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
  d.writer.join();  // it wrote what was queued and flushed the journal
  d.journal_frames.close();
  d.journal_carm.close();

  std::uint64_t dropped = 0, zoom_unlisted = 0;
  Session s = assemble(d.options.out, d.settings, d.streams, dropped, zoom_unlisted);
  RecorderStatistics stats;
  {
    std::lock_guard lock(d.mutex);
    d.stats.carm_samples -= dropped;
    d.stats.carm_refused += dropped;
    d.stats.carm_zoom_unlisted = zoom_unlisted;
    stats = d.stats;
  }
  std::error_code ignored;
  if (s.frames.empty()) {
    d.write_report(stats, nullptr, false);
    fs::remove_all(journal_of(d.options.out), ignored);
    throw std::runtime_error("nothing was recorded: no frame arrived (video: " + stats.video_reason + "); see " +
                             (d.options.out / "record_report.json").string());
  }
  try {
    write_session_files(d.options.out, s);  // frames are kept even without geometry
  } catch (const std::exception& e) {
    // The journal stays: once the disk has room, the recording is recovered from it.
    {
      std::lock_guard lock(d.mutex);
      d.stats.last_error = std::string("the session files could not be written: ") + e.what();
      stats = d.stats;
    }
    d.write_report(stats, nullptr, false);
    throw std::runtime_error(stats.last_error + "; the journal is kept: once the disk has room, `evarnode record --recover " +
                             d.options.out.string() + "` writes them");
  }
  d.write_report(stats, &s, false);
  sync_session_files(d.options.out);
  fs::remove_all(journal_of(d.options.out), ignored);
  if (s.carm.empty())
    throw std::runtime_error(std::to_string(s.frames.size()) + " frames were recorded but no C-arm sample (C-arm: " +
                             stats.carm_reason + "): " + d.options.out.string() +
                             " holds the frames without geometry; it replays, but cannot be deformed or overlaid");
  return s;
}

}  // namespace evar::session
