// `evarnode record`: a live session from the frame grabber and the C-arm link, written in
// the session format (docs/SESSION_FORMAT.md) with live statistics on the terminal; and
// `evarnode record --recover OUT`, the session of a recording that was killed.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <thread>

#include "commands.hpp"
#include "evar/base/input_error.hpp"
#include "evar/geometry/video_mapping.hpp"
#include "evar/geometry/carm_projection.hpp"
#include "evar/node/logging.hpp"
#include "evar/session/session_recorder.hpp"
#include "interrupt.hpp"
#include "node_config.hpp"
#include "progress_bar.hpp"
#include "source_factory.hpp"

namespace evar::app {

namespace {

// The C-arm link's notices since `before` (each once; the source rate-limits them). More
// than the recorder keeps between two looks are counted, not lost silently.
void log_new_notices(const session::RecorderStatistics& now, const session::RecorderStatistics& before) {
  const std::uint64_t fresh = now.carm_notices - before.carm_notices;
  const auto kept = static_cast<std::uint64_t>(now.recent_carm_notices.size());
  if (fresh > kept) node::log().warn("C-arm link: {} notices came too fast to log; the last {} follow", fresh - kept, kept);
  for (std::size_t i = static_cast<std::size_t>(kept - std::min(fresh, kept)); i < now.recent_carm_notices.size(); ++i)
    node::log().warn("{}", now.recent_carm_notices[i]);
}

int run_recover(const std::filesystem::path& directory) {
  node::log().info("recovering the recording in {} from its journal", directory.string());
  const session::RecoveredRecording r = session::recover_recording(directory);
  node::log().info("{}: {} frames and {} C-arm states recovered", directory.string(), r.session.frames.size(), r.carm_samples);
  if (r.frames_lost > 0)
    node::log().warn("{} of the {} journaled frames were left out: their PNG is missing or was cut short by the end of the recorder",
               r.frames_lost, r.frames_journaled);
  if (r.cut_row_skipped) node::log().info("a journal row cut in half by the end of the recorder was skipped");
  if (r.partial_files_removed > 0)
    node::log().info("{} file(s) the end of the recorder left half written were removed", r.partial_files_removed);
  node::log().info("report: {}", (directory / "record_report.json").string());
  return 0;
}

}  // namespace

int run_record(const RecordCommand& cmd) {
  if (!cmd.recover.empty()) return run_recover(cmd.recover);
  auto frames = make_frame_source(cmd.frames);
  auto carm = make_carm_source(cmd.carm);
  session::RecorderOptions o;
  o.out = cmd.out;
  o.scene = cmd.scene;
  o.ct_to_carm = geometry::read_registration(cmd.registration);
  o.pixel_spacing_mm = cmd.pixel_spacing_mm;
  if (!cmd.video_mapping.empty()) {
    if (cmd.detector_px.size() != 2)
      throw base::InputError("record: --video-mapping needs --detector-px COLS ROWS (the detector behind the video output)");
    o.video_mapping = geometry::read_video_mapping(cmd.video_mapping);
    o.detector_px = {cmd.detector_px[0], cmd.detector_px[1]};
  } else if (!cmd.detector_px.empty() && cmd.zoom_modes.empty()) {
    throw base::InputError("record: --detector-px goes with --video-mapping (without it the frames are the detector's own)");
  }
  if (!cmd.zoom_modes.empty()) {
    const NodeConfig config = read_node_config(cmd.zoom_modes);
    if (config.zoom_modes.empty())
      throw base::InputError(cmd.zoom_modes.string() + ": zoom_modes: missing (record --zoom-modes takes a node.json that lists them)");
    const geometry::DetectorSpec& d = *config.detector;  // read_node_config requires it with zoom_modes
    if (std::abs(d.col_spacing_mm - cmd.pixel_spacing_mm) > 1e-9 || std::abs(d.row_spacing_mm - cmd.pixel_spacing_mm) > 1e-9)
      throw base::InputError("record: --pixel-spacing " + std::to_string(cmd.pixel_spacing_mm) + " mm is not " +
                             cmd.zoom_modes.string() + "'s detector spacing (" + std::to_string(d.col_spacing_mm) + " x " +
                             std::to_string(d.row_spacing_mm) + " mm, square pixels needed)");
    if (!cmd.detector_px.empty() && (cmd.detector_px[0] != d.cols || cmd.detector_px[1] != d.rows))
      throw base::InputError("record: --detector-px differs from " + cmd.zoom_modes.string() + "'s detector (" +
                             std::to_string(d.cols) + " x " + std::to_string(d.rows) + "); leave it out");
    o.detector_px = {d.cols, d.rows};
    o.zoom_modes = config.zoom_modes;
    o.zoom_mode = config.zoom_mode;
  }
  o.device_thickness_mm = cmd.device_thickness_mm;
  session::SessionRecorder recorder(o, *frames, *carm);
  node::log().info("recording {} and {} into {}", frames->description(), carm->description(), cmd.out.string());
  node::log().info("stop with Ctrl-C or SIGTERM{}{}", cmd.seconds ? fmt::format(", or after {:g} s", *cmd.seconds) : "",
             cmd.frames_to_write ? fmt::format(", or after {} frames", *cmd.frames_to_write) : "");

  const InterruptGuard interrupt;
  recorder.start();
  StatusLine status;
  std::uint64_t last_frames = 0;
  session::RecorderStatistics s, shown;
  for (;;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    s = recorder.statistics();
    // State changes are news: a stalled grabber or a silent C-arm is said at once.
    if (s.video != shown.video || s.video_reason != shown.video_reason)
      (acquisition::is_live(s.video) ? node::log().info("video: {}", s.video_reason) : node::log().warn("video: {}", s.video_reason));
    if (s.carm != shown.carm || s.carm_reason != shown.carm_reason)
      (acquisition::is_live(s.carm) ? node::log().info("C-arm: {}", s.carm_reason) : node::log().warn("C-arm: {}", s.carm_reason));
    log_new_notices(s, shown);
    shown = s;
    if (const auto since = status.due()) {
      const auto fs = frames->statistics();
      status.print(fmt::format("{:7.1f} s  frames {} written {} (dropped {}, not recorded {})  {:5.1f} fps  |  C-arm {} samples",
                               s.seconds, s.frames_received, s.frames_written, fs.dropped,
                               s.frames_not_recorded + s.frames_refused + s.frames_write_failed,
                               static_cast<double>(s.frames_received - last_frames) / *since, s.carm_samples));
      last_frames = s.frames_received;
    }
    if (interrupt.interrupted() || (cmd.seconds && s.seconds >= *cmd.seconds) ||
        (cmd.frames_to_write && s.frames_written >= static_cast<std::uint64_t>(*cmd.frames_to_write)))
      break;
  }
  status.finish();
  if (interrupt.interrupted()) node::log().info("{}: finishing the recording", ::strsignal(interrupt.signal_received()));
  const session::Session session = recorder.finish();
  s = recorder.statistics();
  log_new_notices(s, shown);
  node::log().info("{}: {} frames and {} C-arm states in {:.1f} s; {} frames dropped by the source, {} not recorded",
             cmd.out.string(), session.frames.size(), session.carm.size(), s.seconds, frames->statistics().dropped,
             s.frames_not_recorded + s.frames_refused + s.frames_write_failed);
  if (s.carm_refused > 0) node::log().warn("{} C-arm states had values the format refuses and were not recorded", s.carm_refused);
  if (s.carm_zoom_unlisted > 0 && cmd.zoom_modes.empty())
    node::log().warn("{} C-arm states said a zoom mode, but the recording lists none (record --zoom-modes node.json): "
                     "the session takes their frames as the detector's",
                     s.carm_zoom_unlisted);
  else if (s.carm_zoom_unlisted > 0)
    node::log().warn("{} C-arm states were in a zoom mode {} does not list: recorded as said, their frames have no known "
                     "field (not evaluated or exported until the mode is added to the session's zoom_modes)",
                     s.carm_zoom_unlisted, cmd.zoom_modes.string());
  if (!s.last_error.empty()) node::log().warn("last problem: {}", s.last_error);
  node::log().info("report: {}", (cmd.out / "record_report.json").string());
  return 0;
}

}  // namespace evar::app
