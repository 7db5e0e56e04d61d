#include <nlohmann/json.hpp>
#include <stdexcept>

#include "csv_table.hpp"
#include "evar/base/input_error.hpp"
#include "evar/base/input_file.hpp"
#include "recording_journal.hpp"

namespace evar::session {

using namespace recording;

RecoveredRecording recover_recording(const std::filesystem::path& directory) {
  using detail::CutLastLine;
  using detail::fail;
  using detail::first_line_is;
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
  const bool zoom_column = first_line_is(carm_csv, kJournalCArmHeader);
  result.cut_row_skipped |= for_each_row(carm_csv, zoom_column ? kJournalCArmHeader : kJournalCArmHeaderWithoutZoom,
                                         zoom_column ? 12 : 11, CutLastLine::Skip,
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
    if (zoom_column) s.zoom_mode = number<int>(carm_csv, line, "zoom_mode", f[11]);
    if (const auto problem = carm_sample_problem(sample_of(s, host_ns)); !problem.empty()) fail(carm_csv, line, problem);
    streams.states.push_back(s);
  });

  // Writes the kill cut short before their rename (a frame, the report) left their partial
  // files; nothing reads them.
  for (const fs::path& folder : {directory, directory / "frames"}) {
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(folder, ec))
      if (entry.is_regular_file(ec) && entry.path().filename().string().find(".partial-") != std::string::npos &&
          fs::remove(entry.path(), ec))
        ++result.partial_files_removed;
  }

  std::uint64_t dropped = 0, zoom_unlisted = 0;
  result.session = assemble(directory, settings, streams, dropped, zoom_unlisted);
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
                         {"carm_zoom_unlisted", zoom_unlisted},
                         {"cut_row_skipped", result.cut_row_skipped},
                         {"partial_files_removed", result.partial_files_removed}};
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
