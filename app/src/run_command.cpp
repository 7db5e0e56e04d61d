// `evarnode run`: the live node on hardware sources (node.json) or on a replayed session,
// with its outputs (video, snapshots, OpenIGTLink, window), a JSON report and, on sessions
// with ground truth, the ostium distances of what it showed.

#include <algorithm>
#include <tuple>
#include <cstdio>
#include <filesystem>
#include <map>
#include <sstream>
#include <thread>
#include <vector>

#include "commands.hpp"
#include "evar/geometry/carm_projection.hpp"
#include "evar/base/input_error.hpp"
#include "evar/node/live_node.hpp"
#include "evar/node/logging.hpp"
#include "evar/node/output_sinks.hpp"
#include "evar/session/session_replay.hpp"
#include "interrupt.hpp"
#include "json_file.hpp"
#include "node_config.hpp"
#include "preload_memory.hpp"
#include "progress_bar.hpp"
#include "session_evaluation.hpp"

namespace evar::app {

namespace {

nlohmann::json to_json(const node::Percentiles& p) { return {{"p50", p.p50}, {"p99", p.p99}, {"max", p.max}, {"n", p.n}}; }

nlohmann::json to_json(const std::vector<std::filesystem::path>& files) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& f : files) a.push_back(f.string());
  return a;
}

// Frames per second of a session: the median interval between frames.
double session_fps(const session::Session& s) {
  std::vector<double> dt;
  for (std::size_t i = 1; i < s.frames.size(); ++i)
    if (s.frames[i].timestamp_ns > s.frames[i - 1].timestamp_ns)
      dt.push_back(static_cast<double>(s.frames[i].timestamp_ns - s.frames[i - 1].timestamp_ns) * 1e-9);
  if (dt.empty()) return 15.0;
  std::nth_element(dt.begin(), dt.begin() + static_cast<long>(dt.size() / 2), dt.end());
  return std::clamp(1.0 / dt[dt.size() / 2], 1.0, 120.0);
}

}  // namespace

int run_node(const RunCommand& cmd) {
  std::optional<NodeConfig> config;
  if (!cmd.config.empty()) config = read_node_config(cmd.config);
  if (cmd.replay.empty() && !config) throw base::InputError("run: give --config node.json or --replay SESSION");

  std::optional<session::Session> session;
  node::NodeOptions options;
  std::filesystem::path scene_path;
  double fps = 30.0;
  if (!cmd.replay.empty()) {
    session = session::read_session(cmd.replay);
    if (session->frames.empty()) throw base::InputError(cmd.replay.string() + ": the session has no frames");
    scene_path = cmd.replay / session->scene;
    options.detector = session->detector;
    options.video_mapping = session->video_mapping;  // checked against the detector when read
    options.zoom_modes = session->zoom_modes;        // and against each zoom mode
    // Frames and C-arm samples of a session share the recording's clock, whatever the speed.
    options.frames_on_carm_clock = true;
    options.registration = session->ct_to_carm;
    fps = session_fps(*session);
    // A C-arm that reports only when something changes leaves long gaps between samples
    // while still; geometry is stale only beyond the longest gap the session has.
    std::int64_t gap_ns = 0;
    for (std::size_t i = 1; i < session->carm.size(); ++i)
      gap_ns = std::max(gap_ns, session->carm[i].timestamp_ns - session->carm[i - 1].timestamp_ns);
    options.timeline.stale_after =
        std::max(options.timeline.stale_after, std::chrono::milliseconds(gap_ns / 1'000'000 + 250));
    // Replayed faster than recorded, each C-arm sample arrives early by up to the gap before
    // it: not a clock set forward, so not held (GeometryTimelineOptions::ahead_after).
    options.timeline.ahead_after =
        std::max(options.timeline.ahead_after, std::chrono::milliseconds(gap_ns / 1'000'000 + 250));
  } else {
    if (!config->scene) throw base::InputError(config->file.string() + ": scene: missing (needed for live sources)");
    if (!config->registration) throw base::InputError(config->file.string() + ": registration: missing");
    if (!config->detector) throw base::InputError(config->file.string() + ": detector: missing");
    if (!config->frames) throw base::InputError(config->file.string() + ": frames: missing");
    if (!config->carm) throw base::InputError(config->file.string() + ": carm: missing");
    scene_path = *config->scene;
    options.registration = geometry::read_registration(*config->registration);
    options.detector = *config->detector;
    options.video_mapping = config->video_mapping;
    options.zoom_modes = config->zoom_modes;
    options.zoom_mode = config->zoom_mode;
    // With zoom modes each mode's image must fit the mapping (node::check_options names the mode).
    if (options.video_mapping && options.zoom_modes.empty())
      if (const auto problem = geometry::video_mapping_fit_problem(*options.video_mapping, options.detector.cols,
                                                                   options.detector.rows);
          !problem.empty())
        throw base::InputError(config->file.string() + ": video_mapping: " + problem + " (detector " +
                               std::to_string(options.detector.cols) + " x " + std::to_string(options.detector.rows) + ")");
    // The video file runs at the rate asked for, else at the rate asked of the source.
    fps = config->fps.value_or(config->frames->fps.value_or(30.0));
  }
  if (config) {
    options.candidate.device_diameter_mm = config->device_diameter_mm;
    options.candidate.min_contrast = config->min_contrast;
    options.adaptation.reconstruction.min_separation_deg = config->min_separation_deg;
    options.pairs.max_gap_ns = static_cast<std::int64_t>(config->max_view_gap_s * 1e9);
    options.pelvis.enabled = config->pelvis;
    if (config->geometry_stale_ms)
      options.timeline.stale_after = std::chrono::milliseconds(static_cast<std::int64_t>(*config->geometry_stale_ms));
  }
  if (!cmd.pelvis) options.pelvis.enabled = false;
  const auto mode = overlay::parse_roadmap_mode(cmd.mode);
  if (!mode) throw std::invalid_argument("--mode " + cmd.mode + ": expected undeformed, adapted or both");
  options.mode = *mode;
  options.backpressure = session.has_value();
  const geometry::Scene scene = geometry::load_scene(scene_path);

  std::filesystem::create_directories(cmd.out);
  // A restarted service writes into the same directory: nothing of the earlier run is lost
  // (the video and pictures are kept by their sinks).
  for (const char* report : {"run_report.json", "eval.md"})
    if (const auto kept = node::set_aside_earlier(cmd.out / report)) node::log().info("the earlier run's {} is kept as {}", report, kept->string());
  std::vector<std::unique_ptr<node::OutputSink>> sinks;
  node::VideoSink* video = nullptr;
  node::SnapshotSink* snapshots = nullptr;
  node::IgtlSink* igtl = nullptr;
  if (!cmd.no_video) {
    auto s = std::make_unique<node::VideoSink>(cmd.out / cmd.video, fps, cmd.video_budget_mb << 20);
    video = s.get();
    sinks.push_back(std::move(s));
  }
  {
    auto s = std::make_unique<node::SnapshotSink>(cmd.out / "snapshots", cmd.snapshot_budget_mb << 20);
    snapshots = s.get();
    sinks.push_back(std::move(s));
  }
  if (cmd.igtl) {
    overlay::IgtlServerOptions o;
    o.bind_address = cmd.igtl_bind;
    o.port = cmd.igtl_port;
    // The image sent is the frame as shown: under a video mapping its pixels are the monitor's.
    // Each frame says its own spacing (a zoom mode's); this one is for frames of no known mode.
    const geometry::DetectorSpec image = options.zoom_modes.empty() ? options.detector : geometry::image_detector(options.zoom_modes.front());
    const auto mapping = options.zoom_modes.empty() ? options.video_mapping : geometry::frame_mapping(options.video_mapping, options.zoom_modes.front());
    const double video_px_per_detector_px =
        mapping ? geometry::VideoToDetector(*mapping, image.cols, image.rows).video_px_per_detector_px() : 1.0;
    auto s = std::make_unique<node::IgtlSink>(o, scene, image.col_spacing_mm / video_px_per_detector_px, 15.0);
    node::log().info("OpenIGTLink server on {}:{} (3D Slicer: OpenIGTLinkIF, client to this port)", cmd.igtl_bind, s->port());
    igtl = s.get();
    sinks.push_back(std::move(s));
  }
  EvaluationSink* evaluation = nullptr;
  if (session && session->truth) {
    auto s = std::make_unique<EvaluationSink>(*session, scene);
    evaluation = s.get();
    sinks.push_back(std::move(s));
  }
  std::atomic<bool> quit{false};
  node::LiveNode* node_ptr = nullptr;
  if (cmd.display) {
    node::WindowSink::Actions actions;
    actions.cycle_mode = [&] {
      const auto m = node_ptr->mode();
      node_ptr->set_mode(m == overlay::RoadmapMode::Both       ? overlay::RoadmapMode::Adapted
                         : m == overlay::RoadmapMode::Adapted ? overlay::RoadmapMode::Undeformed
                                                              : overlay::RoadmapMode::Both);
    };
    actions.snapshot = [&] { snapshots->request(); };
    actions.quit = [&] { quit = true; };
    sinks.push_back(std::make_unique<node::WindowSink>(cmd.fullscreen, actions));
  }

  // The sources before the node: destroyed after it, so a node left running by an
  // exception stops (in its destructor) while its sources still exist.
  std::unique_ptr<session::SessionReplay> replay;
  std::unique_ptr<acquisition::FrameSource> live_frames;
  std::unique_ptr<acquisition::CArmGeometrySource> live_carm;
  node::LiveNode node(scene, options, std::move(sinks));
  node_ptr = &node;
  acquisition::FrameSource* frames = nullptr;
  acquisition::CArmGeometrySource* carm = nullptr;
  if (session) {
    if (cmd.preload) check_preload_memory(*session);
    replay = std::make_unique<session::SessionReplay>(*session,
                                                  session::ReplayOptions{cmd.fast ? 0.0 : cmd.speed, cmd.loops, cmd.preload});
    frames = &replay->frames();
    carm = &replay->carm();
  } else {
    FrameSourceSpec spec = *config->frames;
    if (!spec.width && !spec.height) {
      // Ask the grabber for the frames' size (a camera's current region may be another): the
      // detector's, or the video output's.
      spec.width = options.video_mapping ? options.video_mapping->video_cols : options.detector.cols;
      spec.height = options.video_mapping ? options.video_mapping->video_rows : options.detector.rows;
      if (!options.video_mapping && !options.zoom_modes.empty()) {
        // The image of the mode fixed, else of the first listed (the mode the C-arm starts in
        // is not known before its link says it).
        const geometry::ZoomMode& z = options.zoom_mode != 0 ? *geometry::find_zoom_mode(options.zoom_modes, options.zoom_mode)
                                                             : options.zoom_modes.front();
        std::tie(spec.width, spec.height) = geometry::frame_size_px(std::nullopt, z);
      }
    }
    live_frames = make_frame_source(spec);
    live_carm = make_carm_source(*config->carm);
    frames = live_frames.get();
    carm = live_carm.get();
  }
  node::log().info("running on {} and {}; roadmap {}; outputs in {}", frames->description(), carm->description(), cmd.mode,
             cmd.out.string());
  const InterruptGuard ctrl_c;
  const auto t0 = std::chrono::steady_clock::now();
  node.start(*frames, *carm);
  {
    ProgressBar bar("frames", cmd.progress && session.has_value());
    StatusLine status;
    for (;;) {
      if (replay) {
        const bool done = replay->wait(std::chrono::milliseconds(100));
        const auto p = replay->progress();
        bar.update(p.frames, p.frames_per_loop * static_cast<std::size_t>(std::max(cmd.loops, 1)));
        if (done) break;
      } else {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        if (status.due()) {
          const node::NodeStatistics s = node.statistics();
          status.print(fmt::format("frames {} shown {} (dropped {})  latency p50 {:.1f} ms  models {}", s.frames_in,
                                   s.frames_composited, s.dropped_input + s.dropped_output, s.latency_ms.p50,
                                   s.adaptations));
        }
      }
      const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      if (ctrl_c.interrupted() || quit.load() || (cmd.seconds && elapsed >= *cmd.seconds)) break;
    }
  }
  node.stop();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const node::NodeStatistics s = node.statistics();
  if (replay && !replay->error().empty()) node::log().error("replay ended early: {}", replay->error());

  nlohmann::json report = {
      {"source", frames->description()},
      {"seconds", seconds},
      {"frames", {{"in", s.frames_in}, {"composited", s.frames_composited}, {"with_roadmap", s.frames_with_roadmap},
                  {"dropped_input", s.dropped_input}, {"dropped_output", s.dropped_output},
                  {"lost_by_source", s.frames_lost_by_source}, {"wrong_size", s.frames_wrong_size}, {"zoom_unknown", s.frames_zoom_unknown},
                  {"held_while_no_video", s.frames_held},
                  {"stale_geometry", s.stale_geometry_frames}, {"c_arm_moving", s.moving_frames}}},
      {"analysis", {{"analysed", s.analysed}, {"skipped_busy", s.analysis_skipped},
                    {"not_fluoroscopy", s.frames_not_fluoroscopy},
                    {"video_mapping_checks", s.video_mapping_checks}, {"video_mapping_misfits", s.video_mapping_misfits},
                    {"last_video_mapping_misfit", s.last_video_mapping_misfit},
                    {"orientation_checks", s.orientation_checks}, {"orientation_misfits", s.orientation_misfits},
                    {"last_orientation_misfit", s.last_orientation_misfit},
                    {"orientation_alerts", s.orientation_alerts}, {"last_orientation_alert", s.last_orientation_alert},
                    {"waited_for_adaptation", s.analysis_waited}, {"candidates", s.candidates},
                    {"pairs", s.pairs}, {"pairs_superseded", s.pairs_superseded}}},
      {"adaptation", {{"models", s.adaptations}, {"failures", s.adaptation_failures}, {"last_failure", s.last_failure},
                      {"again_after_pelvis", s.readaptations},
                      {"models_device_outside", s.models_device_outside},
                      {"last_device_outside_length_mm", s.last_device_outside_length_mm},
                      {"last_device_outside_max_depth_mm", s.last_device_outside_max_depth_mm},
                      {"ready_after_second_view_ms", to_json(s.adaptation_ms)}}},
      {"latency_ms", to_json(s.latency_ms)},
      {"video_stalls", s.video_stalls},
      {"frame_loss_alerts", s.frame_loss_alerts},
      {"carm_notices", s.carm_notices},
      {"last_carm_notice", s.last_carm_notice},
      {"sink_errors", s.sink_errors},
      {"outputs", {{"video", video ? (cmd.out / cmd.video).string() : ""},
                   {"video_frames", video ? video->frames() : 0},
                   {"video_segments", to_json(video ? video->segments() : std::vector<std::filesystem::path>{})},
                   {"video_segments_deleted_for_budget", video ? video->segments_deleted() : 0},
                   {"snapshots", to_json(snapshots->kept())},
                   {"snapshots_deleted_for_budget", snapshots->deleted()},
                   {"igtl_port", igtl ? igtl->port() : 0},
                   {"igtl_messages", igtl ? igtl->statistics().messages_sent : 0}}}};
  if (s.carm_clock_offset_ns) report["carm_clock_offset_ns"] = *s.carm_clock_offset_ns;
  report["pelvis"] = {{"looked_for", options.pelvis.enabled && scene.pelvis.V.rows() > 0},
                      {"views", s.pelvis_views},
                      {"registrations", s.pelvis_registrations},
                      {"found", s.pelvis_found},
                      {"models_moved", s.pelvis_moves},
                      {"last", s.last_pelvis},
                      {"shift_mm", s.pelvis_shift_mm ? nlohmann::json(*s.pelvis_shift_mm) : nlohmann::json(nullptr)},
                      {"turn_deg", s.pelvis_turn_deg}};
  std::size_t evaluated = 0;
  if (evaluation) {
    const std::vector<LandmarkError> errors = evaluation->result();
    evaluated = evaluation->frames();
    nlohmann::json lm = nlohmann::json::array();
    std::ostringstream md;
    md << "| landmark | frames | initial (mm) | adapted (mm) | initial vertical (mm) | adapted vertical (mm) |\n"
          "|---|---|---|---|---|---|\n";
    std::vector<double> before, after;
    char row[200];
    for (const auto& l : errors) {
      lm.push_back(to_json(l));
      std::snprintf(row, sizeof row, "| %s | %d | %.2f | %.2f | %.2f | %.2f |\n", l.label.c_str(), l.frames, l.initial_mm,
                    l.adapted_mm, l.initial_vertical_mm, l.adapted_vertical_mm);
      md << row;
      before.push_back(l.initial_mm);
      after.push_back(l.adapted_mm);
    }
    const Statistic b = statistic(before), a = statistic(after);
    std::snprintf(row, sizeof row, "| **mean ± sd** | | **%.2f ± %.2f** | **%.2f ± %.2f** | | |\n", b.mean, b.sd, a.mean, a.sd);
    md << row;
    report["evaluation"] = {{"frames", evaluated}, {"landmarks", lm}};
    write_text(cmd.out / "eval.md",
               "# Ostium distances in the frames shown with the adapted model\n\n"
               "2D distance between each true ostium and its landmark projected from the preoperative (initial) and the\n"
               "adapted model, in mm at the isocenter, averaged over the " +
                   std::to_string(evaluated) + " frames shown with an adapted model and a settled C-arm.\n\n" + md.str());
    std::fputs(md.str().c_str(), stdout);
  }
  write_json(cmd.out / "run_report.json", report);
  node::log().info("{} frames in {:.1f} s: {} shown ({} with the roadmap), {} dropped; latency p50 {:.1f} ms, p99 {:.1f} ms; "
             "{} model(s), {} failed",
             s.frames_in, seconds, s.frames_composited, s.frames_with_roadmap, s.dropped_input + s.dropped_output,
             s.latency_ms.p50, s.latency_ms.p99, s.adaptations, s.adaptation_failures);
  if (video) {
    node::log().info("video: {} ({} frames written in all)", (cmd.out / cmd.video).string(), video->frames());
    if (!video->segments().empty() || video->segments_deleted())
      node::log().info("video: {} earlier segment(s) beside it, {} older one(s) deleted for the {} MiB budget",
                 video->segments().size(), video->segments_deleted(), cmd.video_budget_mb);
  }
  node::log().info("snapshots: {} in {} ({:.1f} MiB){}", snapshots->kept().size(), (cmd.out / "snapshots").string(),
             static_cast<double>(snapshots->bytes()) / (1 << 20),
             snapshots->deleted() ? "; " + std::to_string(snapshots->deleted()) + " older model pictures deleted for the " +
                                        std::to_string(cmd.snapshot_budget_mb) + " MiB budget"
                                  : std::string());
  node::log().info("report: {}{}", (cmd.out / "run_report.json").string(),
             evaluated ? "; evaluation: " + (cmd.out / "eval.md").string() : "");
  return 0;
}

}  // namespace evar::app
