#include "evar/session/session_recorder.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <fstream>
#include <limits>
#include <mutex>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <thread>
#include <vector>

#include "csv_table.hpp"
#include "evar/acquisition/clock_offset.hpp"
#include "evar/base/atomic_file.hpp"
#include "evar/base/unique_fd.hpp"
#include "evar/geometry/image_header.hpp"
#include "evar/base/input_error.hpp"
#include "evar/base/input_file.hpp"
#include "evar/geometry/json_fields.hpp"
#include "evar/geometry/scene.hpp"

namespace evar::session {

namespace fs = std::filesystem;
using acquisition::CArmState;
using acquisition::Frame;
using acquisition::PixelFormat;
using acquisition::StreamState;

// The session's own files and their directories on the disk (fsync) before the journal that
// could rebuild them goes: a power cut right after finishing must not leave them empty.
// Frames are not synced one by one (an hour of them would take minutes).
void sync_session_files(const fs::path& dir) {
  for (const fs::path& p : {dir / "session.json", dir / "carm.csv", dir / "frames" / "index.csv",
                            dir / "record_report.json", dir / "frames", dir}) {
    const base::UniqueFd fd(::open(p.c_str(), O_RDONLY | O_CLOEXEC));
    if (!fd) continue;  // a file the session does not have
    ::fsync(fd.get());
  }
}

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

namespace {

std::int64_t ns_of(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
}

CArmSample sample_of(const CArmState& s, std::int64_t timestamp_ns) {
  CArmSample c;
  c.timestamp_ns = timestamp_ns;
  c.primary_deg = s.primary_deg;
  c.secondary_deg = s.secondary_deg;
  c.sid_mm = s.sid_mm;
  c.sod_mm = s.sod_mm;
  c.table_mm = {s.table_mm[0], s.table_mm[1], s.table_mm[2]};
  c.fluoro_on = s.fluoro_on;
  c.moving = s.moving;
  return c;
}

}  // namespace

std::vector<CArmSample> carm_on_host_clock(const std::vector<CArmState>& states) {
  std::vector<acquisition::ClockPair> pairs;
  pairs.reserve(states.size());
  for (const CArmState& s : states) pairs.push_back({s.device_time_ns, ns_of(s.host_arrival)});
  const std::vector<std::int64_t> host_ns = acquisition::device_times_on_host(pairs);
  std::vector<CArmSample> out;
  out.reserve(states.size());
  for (std::size_t i = 0; i < states.size(); ++i) out.push_back(sample_of(states[i], host_ns[i]));
  return out;
}

namespace {

// The journal of a recording in progress (docs/SESSION_FORMAT.md): what finish() needs, on
// disk as it arrives, so a recording that never reaches finish() can still become a session.
constexpr const char* kJournalFormat = "evarnode-recording-journal";
constexpr const char* kJournalFramesHeader =
    "frame,timestamp_ns,source,file,cols,rows,device_clock,device_time_ns,host_arrival_ns";
constexpr const char* kJournalCArmHeader =
    "device_time_ns,host_arrival_ns,primary_deg,secondary_deg,sid_mm,sod_mm,table_x_mm,table_y_mm,table_z_mm,fluoro_on,"
    "moving";
// C-arm rows and the report reach the disk at least this often (frame rows with each frame).
constexpr auto kJournalPeriod = std::chrono::seconds(1);

fs::path journal_of(const fs::path& out) { return out / "journal"; }

// What the session files need besides the streams (journal/recording.json).
struct RecordingSettings {
  Eigen::Matrix4d ct_to_carm = Eigen::Matrix4d::Identity();
  double device_thickness_mm = 0.0;
  double pixel_spacing_mm = 0.0;  // at the detector, square pixels
};

// A recording's streams as they arrived, before they become a session.
struct RecordedStreams {
  std::vector<FrameRecord> frames;  // written, in frame order, timed live
  // Frames timed by a device clock: (frame number, clock sample), in frame order.
  std::vector<std::pair<std::int64_t, acquisition::ClockPair>> device_clock_frames;
  std::vector<CArmState> states;            // valid ones, in arrival order
  std::optional<std::pair<int, int>> size;  // the frames' (cols, rows)
};

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

// The session a recording makes, the same from memory (finish) and from the journal
// (recovery). C-arm states whose time on the host clock falls outside the format's range
// are left out and counted in `dropped`.
Session assemble(const fs::path& out, const RecordingSettings& settings, const RecordedStreams& streams,
                 std::uint64_t& dropped) {
  Session s;
  s.directory = out;
  s.scene = "patient/scene.json";
  s.ct_to_carm = settings.ct_to_carm;
  s.device_thickness_mm = settings.device_thickness_mm;
  s.frames = streams.frames;
  map_frames_offline(streams.device_clock_frames, s.frames);
  for (const CArmSample& c : carm_on_host_clock(streams.states)) {
    if (carm_sample_problem(c).empty())
      s.carm.push_back(c);
    else
      ++dropped;
  }
  if (streams.size)
    s.detector = {streams.size->first, streams.size->second, settings.pixel_spacing_mm, settings.pixel_spacing_mm};
  return s;
}

std::string journal_frame_row(const FrameRecord& r, const Frame& f) {
  return std::to_string(r.frame) + "," + std::to_string(r.timestamp_ns) + "," + r.source + "," + r.file.generic_string() +
         "," + std::to_string(f.width) + "," + std::to_string(f.height) + "," + (f.device_clock ? "1" : "0") + "," +
         std::to_string(f.device_time_ns) + "," + std::to_string(ns_of(f.host_arrival)) + "\n";
}

std::string journal_carm_row(const CArmState& s) {
  using detail::exact;
  return std::to_string(s.device_time_ns) + "," + std::to_string(ns_of(s.host_arrival)) + "," + exact(s.primary_deg) + "," +
         exact(s.secondary_deg) + "," + exact(s.sid_mm) + "," + exact(s.sod_mm) + "," + exact(s.table_mm[0]) + "," +
         exact(s.table_mm[1]) + "," + exact(s.table_mm[2]) + "," + (s.fluoro_on ? "1" : "0") + "," + (s.moving ? "1" : "0") +
         "\n";
}

// Through an AtomicFile, so a recorder killed while writing leaves the last whole report.
void write_json_file(const fs::path& file, const nlohmann::ordered_json& j) {
  base::write_file_atomically(file, j.dump(2) + "\n");
}

RecordingSettings read_settings(const fs::path& file) {
  using geometry::detail::bad_field;
  using geometry::detail::member;
  const nlohmann::json j = geometry::detail::parse_json_file(file);
  if (!j.is_object()) bad_field(file, "top level", "expected a JSON object");
  if (member(file, j, "format", "format") != kJournalFormat) bad_field(file, "format", std::string("expected \"") + kJournalFormat + "\"");
  if (member(file, j, "version", "version") != 1) bad_field(file, "version", "unsupported (this build reads version 1)");
  RecordingSettings s;
  const auto& m = member(file, j, "registration", "registration");
  if (!m.is_array() || m.size() != 4) bad_field(file, "registration", "expected 4 rows of 4 numbers");
  for (int r = 0; r < 4; ++r)
    s.ct_to_carm.row(r) =
        geometry::detail::number_array(file, m[static_cast<std::size_t>(r)], "registration[" + std::to_string(r) + "]", 4).transpose();
  s.device_thickness_mm =
      geometry::detail::number_field(file, member(file, j, "device_thickness_mm", "device_thickness_mm"), "device_thickness_mm", 0.0, 15.0, "mm");
  s.pixel_spacing_mm =
      geometry::detail::number_field(file, member(file, j, "pixel_spacing_mm", "pixel_spacing_mm"), "pixel_spacing_mm", 1e-9, 10.0, "mm");
  return s;
}

// Whether a frame's PNG was written whole: its header says the frame's size and it ends with
// the IEND chunk (a recorder killed while writing leaves the file cut short).
bool whole_png(const fs::path& file, int cols, int rows) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return false;
  std::string head(64, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  try {
    const geometry::ImageHeader h = geometry::read_image_header(head, file.string());
    if (h.format != "PNG" || h.width != cols || h.height != rows) return false;
  } catch (const base::InputError&) {
    return false;
  }
  static constexpr unsigned char kIend[12] = {0, 0, 0, 0, 'I', 'E', 'N', 'D', 0xAE, 0x42, 0x60, 0x82};
  std::array<char, 12> tail{};
  in.clear();
  in.seekg(-12, std::ios::end);
  in.read(tail.data(), static_cast<std::streamsize>(tail.size()));
  return in.gcount() == 12 && std::memcmp(tail.data(), kIend, sizeof kIend) == 0;
}

}  // namespace

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
    if (!streams.size) streams.size = std::make_pair(f.width, f.height);
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
          {"source", carm.description()},
          {"last_state", acquisition::to_string(s.carm)},
          {"last_reason", s.carm_reason},
          {"notices", s.carm_notices},
          {"recent_notices", s.recent_carm_notices}}},
        {"last_error", s.last_error},
        {"session_written", session != nullptr}};
    if (session && !session->frames.empty())
      j["frames"]["span_s"] = 1e-9 * static_cast<double>(session->frames.back().timestamp_ns - session->frames.front().timestamp_ns);
    write_json_file(options.out / "record_report.json", j);
  }

  void start_journal() {
    const fs::path dir = journal_of(options.out);
    fs::create_directories(dir);
    nlohmann::ordered_json rows = nlohmann::ordered_json::array();
    for (int r = 0; r < 4; ++r)
      rows.push_back({settings.ct_to_carm(r, 0), settings.ct_to_carm(r, 1), settings.ct_to_carm(r, 2), settings.ct_to_carm(r, 3)});
    write_json_file(dir / "recording.json", {{"format", kJournalFormat},
                                             {"version", 1},
                                             {"registration", rows},
                                             {"device_thickness_mm", settings.device_thickness_mm},
                                             {"pixel_spacing_mm", settings.pixel_spacing_mm}});
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
  impl_->settings = {impl_->options.ct_to_carm, impl_->options.device_thickness_mm.value_or(impl_->scene.device_thickness_mm),
                     impl_->options.pixel_spacing_mm};
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

  std::uint64_t dropped = 0;
  Session s = assemble(d.options.out, d.settings, d.streams, dropped);
  RecorderStatistics stats;
  {
    std::lock_guard lock(d.mutex);
    d.stats.carm_samples -= dropped;
    d.stats.carm_refused += dropped;
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

RecoveredRecording recover_recording(const std::filesystem::path& directory) {
  using detail::CutLastLine;
  using detail::fail;
  using detail::flag;
  using detail::for_each_row;
  using detail::number;
  const fs::path journal = journal_of(directory);
  if (!fs::is_directory(journal)) {
    if (fs::is_regular_file(directory / "session.json"))
      throw base::InputError(directory.string() + ": a finished session (session.json and no journal/); nothing to recover");
    throw base::InputError(journal.string() + ": no recording journal here; recover the --out directory of `evarnode record`");
  }
  const RecordingSettings settings = read_settings(journal / "recording.json");
  RecoveredRecording result;
  RecordedStreams streams;

  const fs::path frames_csv = journal / "frames.csv";
  result.cut_row_skipped |= for_each_row(frames_csv, kJournalFramesHeader, 9, CutLastLine::Skip,
                                         [&](std::size_t line, const std::vector<std::string>& f) {
    FrameRecord r;
    r.frame = number<std::int64_t>(frames_csv, line, "frame", f[0]);
    r.timestamp_ns = number<std::int64_t>(frames_csv, line, "timestamp_ns", f[1]);
    r.source = f[2];
    r.file = f[3];
    const int cols = number<int>(frames_csv, line, "cols", f[4]), rows = number<int>(frames_csv, line, "rows", f[5]);
    const bool device_clock = flag(frames_csv, line, "device_clock", f[6]);
    const acquisition::ClockPair clock{number<std::int64_t>(frames_csv, line, "device_time_ns", f[7]),
                                       number<std::int64_t>(frames_csv, line, "host_arrival_ns", f[8])};
    if (const auto problem = frame_record_problem(r); !problem.empty()) fail(frames_csv, line, problem);
    if (!streams.frames.empty() && r.frame <= streams.frames.back().frame)
      fail(frames_csv, line, "frame: " + std::to_string(r.frame) + " does not increase");
    ++result.frames_journaled;
    if (device_clock) streams.device_clock_frames.push_back({r.frame, clock});  // a clock sample even if its file is lost
    if (!streams.size) streams.size = std::make_pair(cols, rows);
    if (*streams.size != std::make_pair(cols, rows) || !whole_png(directory / "frames" / r.file, cols, rows)) {
      ++result.frames_lost;
      return;
    }
    streams.frames.push_back(std::move(r));
  });

  const fs::path carm_csv = journal / "carm.csv";
  result.cut_row_skipped |= for_each_row(carm_csv, kJournalCArmHeader, 11, CutLastLine::Skip,
                                         [&](std::size_t line, const std::vector<std::string>& f) {
    CArmState s;
    s.device_time_ns = number<std::int64_t>(carm_csv, line, "device_time_ns", f[0]);
    const auto host_ns = number<std::int64_t>(carm_csv, line, "host_arrival_ns", f[1]);
    s.host_arrival = std::chrono::steady_clock::time_point(std::chrono::nanoseconds(host_ns));
    s.primary_deg = number<double>(carm_csv, line, "primary_deg", f[2]);
    s.secondary_deg = number<double>(carm_csv, line, "secondary_deg", f[3]);
    s.sid_mm = number<double>(carm_csv, line, "sid_mm", f[4]);
    s.sod_mm = number<double>(carm_csv, line, "sod_mm", f[5]);
    for (std::size_t k = 0; k < 3; ++k)
      s.table_mm[k] = number<double>(carm_csv, line, k == 0 ? "table_x_mm" : k == 1 ? "table_y_mm" : "table_z_mm", f[6 + k]);
    s.fluoro_on = flag(carm_csv, line, "fluoro_on", f[9]);
    s.moving = flag(carm_csv, line, "moving", f[10]);
    if (const auto problem = carm_sample_problem(sample_of(s, host_ns)); !problem.empty()) fail(carm_csv, line, problem);
    streams.states.push_back(s);
  });

  std::uint64_t dropped = 0;
  result.session = assemble(directory, settings, streams, dropped);
  result.carm_samples = result.session.carm.size();
  if (result.session.frames.empty())
    throw std::runtime_error(directory.string() + ": nothing to recover: " +
                             (result.frames_journaled == 0 ? std::string("the journal holds no frame")
                                                           : "none of the " + std::to_string(result.frames_journaled) +
                                                                 " journaled frames has its PNG whole"));
  write_session_files(directory, result.session);

  // The report the recorder last wrote, said to be recovered (or a new one if it never wrote one).
  nlohmann::ordered_json report;
  try {
    report = nlohmann::ordered_json::parse(base::read_input_file(directory / "record_report.json", base::kJsonLimit));
  } catch (const std::exception&) {  // missing or cut: a new one
  }
  if (!report.is_object()) report = {{"format", "evarnode-record-report"}, {"version", 1}};
  report["in_progress"] = false;
  report["session_written"] = true;
  report["recovered"] = {{"frames_journaled", result.frames_journaled},
                         {"frames_lost", result.frames_lost},
                         {"frames", result.session.frames.size()},
                         {"carm_samples", result.carm_samples},
                         {"carm_dropped_out_of_range", dropped},
                         {"cut_row_skipped", result.cut_row_skipped}};
  write_json_file(directory / "record_report.json", report);
  sync_session_files(directory);
  std::error_code ignored;
  fs::remove_all(journal, ignored);
  if (result.session.carm.empty())
    throw std::runtime_error(std::to_string(result.session.frames.size()) + " frames were recovered but no C-arm sample: " +
                             directory.string() + " holds the frames without geometry; it replays, but cannot be deformed or overlaid");
  return result;
}

}  // namespace evar::session
