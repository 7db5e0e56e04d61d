#include "evar/node/live_node.hpp"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <functional>
#include <limits>
#include <mutex>
#include <optional>
#include <string_view>
#include <thread>

#include <Eigen/Geometry>
#include <numbers>
#include <opencv2/core.hpp>

#include "alert_board.hpp"
#include "evar/geometry/video_area.hpp"
#include "evar/geometry/video_frame.hpp"
#include "evar/node/picture_orientation.hpp"
#include "evar/node/picture_turn.hpp"
#include "frame_field.hpp"
#include "held_frame_policy.hpp"
#include "evar/node/logging.hpp"
#include "latency_window.hpp"
#include "mailbox.hpp"
#include "status_lines.hpp"

namespace evar::node {

namespace {

using Clock = std::chrono::steady_clock;

double ms_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

std::int64_t steady_ns(Clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
}

cv::Mat wrap(const acquisition::Frame& f) {
  const int type = f.format == acquisition::PixelFormat::Mono8 ? CV_8UC1 : CV_16UC1;
  return {f.height, f.width, type, const_cast<std::uint8_t*>(f.pixels.data()), static_cast<std::size_t>(f.stride_bytes)};
}

}  // namespace

class LiveNode::Impl {
 public:
  Impl(const geometry::Scene& scene, NodeOptions options, std::vector<std::unique_ptr<OutputSink>> sinks);
  ~Impl() { stop(); }
  void start(acquisition::FrameSource& frames, acquisition::CArmGeometrySource& carm);
  void stop();
  void set_mode(overlay::RoadmapMode mode) { mode_.store(mode); }
  overlay::RoadmapMode mode() const { return mode_.load(); }
  NodeStatistics statistics() const;
  std::shared_ptr<const PublishedModel> model() const;

 private:
  struct Analysis {  // a frame offered to the analysis thread
    acquisition::Frame frame;
    FrameView view;
    const FrameField* field = nullptr;
  };
  struct BoneView {  // the first analysed frame of a view, offered to the pelvis thread
    cv::Mat detector;
    FrameView view;
    std::string name;
  };
  void on_frame(const acquisition::Frame& frame);
  void compose_loop();
  void analysis_loop();
  void adaptation_loop();
  // The alert for a picture that reads right only turned: the turns as shown, and, with
  // `name_fix` and a single turn, what the video mapping would need (appended to `why`).
  std::string orientation_alert(const std::vector<PictureTurn>& turns, bool name_fix, std::string& why) const;
  // The mapping the frames are shown through, for saying turns as the screen shows them.
  const geometry::VideoMapping* shown_through() const;
  // A picture orientation check counted: what it suspected ("" for nothing), what it said.
  void count_orientation_check(const std::string& misfit, const std::string& alert);
  void pelvis_loop();
  void output_loop();
  void publish(std::shared_ptr<const AdaptedModel> adapted, std::shared_ptr<const geometry::PelvisRegistration> pelvis);
  /// Puts the pair on screen once more for the adaptation thread (the models moved).
  void adapt_again(ViewPair pair);
  /// The models the adaptations bend: moved with the pelvis found, or null (as registered).
  std::shared_ptr<const PelvisMovedModels> moved_models() const;
  /// Samples the source's counts (compose thread) and raises or clears the frame-loss alert.
  void watch_frame_loss(acquisition::FrameLossMonitor& monitor);

  NodeOptions options_;
  // What a frame is, per zoom mode (or the detector's alone): its pixels, the mapping the
  // frames hold them through, the frames' size. Made from options_ once (points into it).
  std::vector<FrameField> fields_;
  std::vector<std::unique_ptr<OutputSink>> sinks_;
  std::unique_ptr<deform::SceneDeformer> deformer_;  // on the scene as registered
  PelvisTracker pelvis_;                             // the pelvis thread's only
  std::shared_ptr<const overlay::RoadmapModel> initial_roadmap_;
  std::atomic<overlay::RoadmapMode> mode_;

  mutable std::mutex source_mutex_;  // frames_ against stop() letting go of it
  acquisition::FrameSource* frames_ = nullptr;  // null when not running
  acquisition::CArmGeometrySource* carm_ = nullptr;
  BoundedQueue<acquisition::Frame> input_;
  BoundedQueue<ComposedFrame> output_;
  LatestSlot<Analysis> analysis_;
  struct PairJob {  // a pair for the adaptation thread
    ViewPair pair;
    bool again = false;  // the pair on screen once more, from the models the pelvis moved (no new view)
  };
  LatestSlot<PairJob> pairs_;
  BoundedQueue<BoneView> bone_views_{4};
  // The models moved with the pelvis (null: as registered); the pair the model on screen came
  // from; whether an adaptation is running. When the models move, the pair on screen is
  // adapted again: by the pelvis thread when no adaptation runs, else by the adaptation
  // thread once it is done (it bent the models as they were).
  mutable std::mutex moved_mutex_;
  std::shared_ptr<const PelvisMovedModels> moved_;
  std::optional<ViewPair> shown_pair_;
  bool adapting_pair_ = false;
  std::atomic<bool> stopping_{false};  // the pelvis thread registers nothing more
  /// The last adaptation's outcome for the analysis thread's selector: used or not, and
  /// the earlier frame of its pair.
  struct PairOutcome {
    bool used = false;
    CandidateId earlier;
  };
  std::mutex outcome_mutex_;
  std::optional<PairOutcome> pair_outcome_;
  // While an adaptation runs, the analysis waits: on a small box the segmentation of every
  // frame would take the core the deformation needs, and a pair formed meanwhile would only
  // wait for it. Then the newest frame is analysed.
  std::atomic<bool> adapting_{false};

  mutable std::mutex timeline_mutex_;
  acquisition::GeometryTimeline timeline_;

  mutable std::mutex model_mutex_;
  std::shared_ptr<const PublishedModel> model_;

  mutable std::mutex stats_mutex_;
  NodeStatistics stats_;
  LatencyWindow latencies_{kLatencyWindow};             // frames
  LatencyWindow adaptation_latencies_{kLatencyWindow};  // adaptations

  AlertBoard alerts_;

  std::thread compose_thread_, analysis_thread_, adaptation_thread_, pelvis_thread_, output_thread_;
  bool running_ = false;
  bool started_ = false;  // once: a stopped node's queues stay closed
};

LiveNode::Impl::Impl(const geometry::Scene& scene, NodeOptions options, std::vector<std::unique_ptr<OutputSink>> sinks)
    : options_((check_options(options), std::move(options))),
      fields_(frame_fields(options_)),
      sinks_(std::move(sinks)),
      pelvis_(scene, options_.pelvis, options_.deform),
      mode_(options_.mode),
      input_(options_.input_queue),
      output_(options_.output_queue),
      timeline_(options_.timeline) {
  deformer_ = std::make_unique<deform::SceneDeformer>(scene, options_.deform);
  initial_roadmap_ = std::make_shared<const overlay::RoadmapModel>(roadmap_model(scene, nullptr));
  auto m = std::make_shared<PublishedModel>();
  m->roadmap = initial_roadmap_;
  m->ready = Clock::now();
  model_ = m;
  log().info("node: {} vessels prepared for deformation in {:.0f} ms", scene.vessels.size(), deformer_->precompute_ms());
  if (pelvis_.active()) {
    stats_.pelvis_status = "looking for it in the bones (two views needed)";
    log().info("node: the pelvis will be looked for in the bones of the fluoroscopy, and the models moved with it");
  } else if (options_.pelvis.enabled) {
    log().info("node: the scene has no pelvis (scene.json \"pelvis\"): the models stay where the registration put them");
  }
  for (std::size_t i = 0; i < scene.vessels.size(); ++i)
    if (!deformer_->proxy_refused(i).empty())
      log().warn("node: vessel '{}' is solved on its own {} vertices (slower, less even): {}", scene.vessels[i].name,
                 scene.vessels[i].mesh.mesh.V.rows(), deformer_->proxy_refused(i));
}

void LiveNode::Impl::start(acquisition::FrameSource& frames, acquisition::CArmGeometrySource& carm) {
  if (running_) throw std::logic_error("node: already started");
  if (started_) throw std::logic_error("node: already run and stopped; a node runs once (make a new one)");
  started_ = true;
  {
    std::lock_guard lock(source_mutex_);
    frames_ = &frames;
  }
  carm_ = &carm;
  compose_thread_ = std::thread([this] { compose_loop(); });
  analysis_thread_ = std::thread([this] { analysis_loop(); });
  adaptation_thread_ = std::thread([this] { adaptation_loop(); });
  pelvis_thread_ = std::thread([this] { pelvis_loop(); });
  output_thread_ = std::thread([this] { output_loop(); });
  running_ = true;
  try {
    carm.start(
        [this](const acquisition::CArmState& s) {
          std::lock_guard lock(timeline_mutex_);
          timeline_.add(s);
        },
        [this](acquisition::StreamState s, const std::string& reason) {
          if (acquisition::is_live(s)) {
            alerts_.clear("carm-source");
            log().info("C-arm link: {} ({})", acquisition::to_string(s), reason);
          } else {
            alerts_.set("carm-source", std::string("C-arm link ") + acquisition::to_string(s) + ": " + reason, std::nullopt);
          }
        },
        // News on a link that has not changed state: shown for a while beside whatever
        // the link's state says, the newest of its kind in place of the one before.
        [this](const acquisition::LinkNotice& notice) {
          {
            std::lock_guard lock(stats_mutex_);
            ++stats_.carm_notices;
            stats_.last_carm_notice = notice.text;
          }
          const bool status = notice.kind == acquisition::LinkNotice::Kind::CArmStatus;
          alerts_.set(status ? "carm-status" : "carm-bad-frames", notice.text, options_.carm_notice_hold);
        });
    frames.start([this](const acquisition::Frame& f) { on_frame(f); },
                 [this](acquisition::StreamState s, const std::string& reason) {
                   if (acquisition::is_live(s)) {
                     alerts_.clear("video-source");
                     log().info("video: {} ({})", acquisition::to_string(s), reason);
                   } else {
                     alerts_.set("video-source", std::string("video ") + acquisition::to_string(s) + ": " + reason, std::nullopt);
                   }
                 });
  } catch (...) {
    stop();
    throw;
  }
}

void LiveNode::Impl::stop() {
  if (!running_) return;
  running_ = false;
  frames_->stop();
  carm_->stop();
  input_.close();
  compose_thread_.join();
  analysis_.close();
  analysis_thread_.join();
  stopping_.store(true);
  bone_views_.close();
  pelvis_thread_.join();
  pairs_.close();
  adaptation_thread_.join();
  output_.close();
  output_thread_.join();
  // The sources may go away once stop() returns: their last counts are kept here.
  std::lock_guard source_lock(source_mutex_);
  const std::uint64_t lost = frames_->statistics().dropped;
  {
    std::lock_guard lock(stats_mutex_);
    stats_.frames_lost_by_source = lost;
  }
  frames_ = nullptr;
  carm_ = nullptr;
}

void LiveNode::Impl::on_frame(const acquisition::Frame& frame) {
  {
    std::lock_guard lock(stats_mutex_);
    ++stats_.frames_in;
  }
  if (options_.backpressure) {
    input_.push_wait(frame);
    return;
  }
  if (input_.push(frame)) {
    const std::size_t dropped = input_.dropped();
    if (dropped == 1 || dropped % 100 == 0)
      log().warn("node: compositing cannot keep up, {} frame(s) dropped so far (the oldest waiting goes)", dropped);
  }
}

void LiveNode::Impl::watch_frame_loss(acquisition::FrameLossMonitor& monitor) {
  acquisition::SequenceStats counts;
  {
    std::lock_guard lock(source_mutex_);
    if (frames_ == nullptr) return;
    counts = frames_->statistics();
  }
  const auto change = monitor.sample(Clock::now(), counts);
  if (!change) return;
  if (!change->losing) {
    alerts_.clear("video-loss");
    return;
  }
  {
    std::lock_guard lock(stats_mutex_);
    ++stats_.frame_loss_alerts;
  }
  // The numbers are those that raised it; the text stays while it lasts (said once).
  alerts_.set("video-loss",
            fmt::format("video losing frames: {} of {} lost by the source in {:.1f} s ({:.0f} %); the image is "
                        "live but jerky (check the camera link)",
                        change->lost, change->expected, static_cast<double>(change->span.count()) / 1000.0,
                        100.0 * change->fraction()),
            std::nullopt);
}

void LiveNode::Impl::compose_loop() {
  overlay::FrameCompositor compositor(options_.compositor);
  acquisition::FrameLossMonitor loss_monitor(options_.frame_loss);
  Clock::time_point last_loss_sample{};
  HeldFramePolicy holding(options_.video_stall, options_.held_frame_interval);
  double last_latency_ms = 0.0;
  std::string layer_error;  // said once in the log; the frames say it themselves
  for (;;) {
    const auto wait = holding.wait(Clock::now(), std::chrono::milliseconds(100));
    // Frames that come but cannot be shown leave the screen as a lost video does.
    const bool hold_instead = holding.hold_instead_of_next(Clock::now());
    std::optional<acquisition::Frame> f = hold_instead ? std::nullopt : input_.pop(wait);
    if (Clock::now() - last_loss_sample >= std::chrono::milliseconds(250)) {
      last_loss_sample = Clock::now();
      watch_frame_loss(loss_monitor);
    }
    std::optional<double> held_s;  // set: f is the last frame shown again, this long after it came
    if (!f && !hold_instead && input_.closed()) break;
    // Stalled: no live frame shown for video_stall, whether none came or none could be shown.
    if (holding.stall_begins(Clock::now())) {
      {
        std::lock_guard lock(stats_mutex_);
        ++stats_.video_stalls;
      }
      alerts_.set("video-stall",
                (holding.showing_fails() ? "no frame shown for " : "no video for ") + std::to_string(options_.video_stall.count()) + " ms",
                std::nullopt);
    }
    if (!f) {
      held_s = holding.take_held(Clock::now());
      if (!held_s) continue;
      f = holding.held().frame;
    }

    // A held frame is shown with the geometry it was first shown with, and changes no
    // alert: the C-arm history may have moved on past its time.
    bool size_ok = false;
    std::optional<acquisition::FrameGeometry> g;
    std::optional<FrameView> view;
    const FrameField* field = nullptr;  // what the frame is: the zoom mode it was taken in
    bool zoom_unknown = false;
    if (held_s) {
      size_ok = holding.held().size_ok;
      g = holding.held().geometry;
      view = holding.held().view;
      field = holding.held().field;
    } else {
      {
        std::lock_guard lock(timeline_mutex_);
        g = options_.frames_on_carm_clock ? timeline_.at_carm_time(f->device_time_ns) : timeline_.at(f->device_time_on_host);
      }
      // The zoom mode the frame was taken in (the C-arm link's, or node.json's); without a
      // geometry yet the frame's size is checked against the mode it would be in.
      std::string zoom_problem;
      field = field_of(fields_, options_, g ? g->state.zoom_mode : 0, zoom_problem);
      if (!field && g) {
        zoom_unknown = true;
        alerts_.set("zoom-mode", zoom_problem + ": no roadmap", options_.alert_hold);
      } else if (field && g) {
        alerts_.clear("zoom-mode");
      }
      // Under a video mapping a frame is the monitor's picture, of the video size.
      if (field) {
        size_ok = f->width == field->frame_cols && f->height == field->frame_rows;
        if (!size_ok)
          alerts_.set("frame-size",
                      "frame " + std::to_string(f->width) + " x " + std::to_string(f->height) + " is not the " +
                          (options_.video_mapping ? "video mapping's " : field->zoom ? "zoom mode's " : "detector's ") +
                          std::to_string(field->frame_cols) +
                          " x " + std::to_string(field->frame_rows) +
                          (field->zoom ? " (" + field->label() + ")" : std::string()) + ": no roadmap",
                      options_.alert_hold);
      } else {
        // No mode to go by: any mode's size will do; a frame of none is said with them all.
        std::string sizes;
        for (const FrameField& k : fields_) {
          size_ok = size_ok || (f->width == k.frame_cols && f->height == k.frame_rows);
          sizes += (sizes.empty() ? "" : ", ") + std::to_string(k.frame_cols) + " x " + std::to_string(k.frame_rows);
        }
        if (!size_ok)
          alerts_.set("frame-size",
                      "frame " + std::to_string(f->width) + " x " + std::to_string(f->height) + " is none of the zoom modes' " +
                          sizes + ": no roadmap",
                      options_.alert_hold);
      }
      if (!g) {
        alerts_.set("geometry", "no C-arm geometry yet: roadmap hidden", std::nullopt);
      } else {
        // The alert names the condition; its changing age goes into the status line.
        if (g->stale) alerts_.set("geometry", "C-arm geometry stale: roadmap at the last known position", std::nullopt);
        else alerts_.clear("geometry");
        if (!g->moving && size_ok && field) {
          try {
            view = field->view(options_.detector, options_.registration, g->state);
          } catch (const std::invalid_argument& e) {
            alerts_.set("geometry-unusable", std::string("C-arm geometry unusable: ") + e.what(), options_.alert_hold);
          }
        }
      }
    }
    const bool analyse = view && !g->stale && g->state.fluoro_on;
    const std::shared_ptr<const PublishedModel> model = this->model();
    bool failed = false;  // the last adaptation
    std::string pelvis_status;
    {
      std::lock_guard lock(stats_mutex_);
      failed = !stats_.last_failure.empty();
      pelvis_status = stats_.pelvis_status;
      if (!held_s) {
        stats_.frames_wrong_size += size_ok || zoom_unknown ? 0 : 1;
        stats_.frames_zoom_unknown += zoom_unknown ? 1 : 0;
        stats_.stale_geometry_frames += g && g->stale ? 1 : 0;
        stats_.moving_frames += g && g->moving ? 1 : 0;
      }
    }
    const overlay::RoadmapMode mode = mode_.load();
    ComposedFrame out;
    // A live frame is not a stall, even while the stall it ends is still to be cleared.
    out.status = {status_lines(g, *model, failed, pelvis_status, mode, last_latency_ms, Clock::now(),
                               field ? field->label() : std::string()),
                  alerts_.current(held_s ? std::string_view() : std::string_view("video-stall"))};
    if (held_s) {
      // First and in the alert colour; its changing age is not an alert of its own (no log).
      out.status.alerts.insert(out.status.alerts.begin(), held_frame_line(holding.showing_fails(), *held_s));
      out.held = true;
    }
    // The frame's pixel at the detector, for outputs that carry it (OpenIGTLink's spacing).
    if (field) out.detector_mm_per_px = field->image.col_spacing_mm / (field->video ? field->video->video_px_per_detector_px() : 1.0);
    if (view) {
      // The roadmap is drawn where the frame shows the detector's pixels.
      out.P_ct = field->video ? geometry::projection_on_video(view->P_ct, *field->video) : view->P_ct;
      const double video_scale = field->video ? field->video->video_px_per_detector_px() : 1.0;
      out.mm_per_px = mm_at_isocenter_per_px(view->view) / video_scale;
      out.detector_view = view;
    }
    try {
      // Before anything reads its rows (a held frame passed it when it came).
      if (!held_s) acquisition::check_layout(*f);
      const int bits = f->format == acquisition::PixelFormat::Mono8 ? 8 : 16;
      out.image = std::make_shared<const overlay::Image>(
          compositor.compose({f->width, f->height, f->stride_bytes, bits, f->pixels.data()},
                             out.P_ct ? &*out.P_ct : nullptr, model->roadmap, mode, out.status));
      out.roadmap = compositor.last_roadmap();
      if (out.P_ct && compositor.last_layer_error() != layer_error) {  // frames without geometry ask for none
        if (!compositor.last_layer_error().empty())
          log().warn("roadmap layer not drawn: {}; frames go on without the roadmap", compositor.last_layer_error());
        else
          log().info("resolved: roadmap layer not drawn: {}", layer_error);
        layer_error = compositor.last_layer_error();
      }
    } catch (const std::exception& e) {
      // The text stays the same from frame to frame (a frame number would log every frame).
      alerts_.set("compose", std::string("frame not shown: ") + e.what(), options_.alert_hold);
      if (!held_s) holding.live_failed();
      continue;
    }
    if (!held_s && holding.live_shown(Clock::now())) alerts_.clear("video-stall");
    out.sequence = f->sequence;
    out.device_time_ns = f->device_time_ns;
    out.model = model;
    if (held_s) {
      std::lock_guard lock(stats_mutex_);
      ++stats_.frames_held;
    } else {
      out.latency_ms = ms_between(f->host_arrival, Clock::now());
      last_latency_ms = out.latency_ms;
      std::lock_guard lock(stats_mutex_);
      ++stats_.frames_composited;
      stats_.frames_with_roadmap += out.roadmap != overlay::RoadmapShown::None ? 1 : 0;
      latencies_.add(out.latency_ms);
    }
    if (options_.backpressure) output_.push_wait(std::move(out));
    else output_.push(std::move(out));
    if (held_s) continue;
    // Shown first, then handed on: the frame moves to the analysis (a copy is kept to be
    // held; assigning into the kept one reuses its buffer). Handing it on before compositing
    // was tried: the segmentation then shares its core with the compositing, and neither
    // the model nor the frame came sooner (docs/BENCHMARKS.md, "The live node").
    HeldFramePolicy::Shown& kept = holding.keep();
    kept.geometry = g;
    kept.view = view;
    kept.size_ok = size_ok;
    kept.field = field;
    if (analyse) {
      kept.frame = *f;
      analysis_.put(Analysis{std::move(*f), *view, field});
    } else {
      kept.frame = std::move(*f);
    }
  }
}

void LiveNode::Impl::analysis_loop() {
  ViewPairSelector selector(options_.adaptation.reconstruction.min_separation_deg, options_.pairs);
  std::optional<FrameView> last_bone_view;
  Clock::time_point last_mapping_check{};
  int misfits_in_a_row = 0;
  while (std::optional<Analysis> a = analysis_.take()) {
    if (adapting_.load()) {
      // Held, not dropped: it may be the last frame of a short run of fluoroscopy. Once the
      // adaptation is done, the newest frame is analysed, this one or one that came since.
      adapting_.wait(true);
      std::optional<Analysis> newer = analysis_.try_take();
      std::lock_guard lock(stats_mutex_);
      ++stats_.analysis_waited;
      if (newer) {
        a = std::move(newer);
        ++stats_.analysis_replaced;  // the held frame is skipped for the newer one
      }
    }
    {
      std::optional<PairOutcome> outcome;
      {
        std::lock_guard lock(outcome_mutex_);
        outcome.swap(pair_outcome_);
      }
      if (outcome) outcome->used ? selector.succeeded(outcome->earlier) : selector.failed(outcome->earlier);
    }
    const auto analysis_start = Clock::now();
    // The device is found on the detector's pixels: under a video mapping they are read
    // back out of the frame's image rectangle.
    const FrameField& field = *a->field;
    const cv::Mat detector = field.video ? geometry::detector_image(wrap(a->frame), *field.video) : wrap(a->frame);
    // The monitor may show something else than fluoroscopy (a menu, a dialog, nothing):
    // not searched for a device, and said while it lasts.
    if (options_.video_mapping) {
      if (const std::string why = geometry::not_fluoroscopy(detector, field.candidate.field_mask); !why.empty()) {
        alerts_.set("not-fluoroscopy", "video: not fluoroscopy: " + why, options_.alert_hold);
        log().debug("frame {}: not fluoroscopy: {}", a->frame.sequence, why);
        std::lock_guard lock(stats_mutex_);
        ++stats_.analysed;
        ++stats_.frames_not_fluoroscopy;
        continue;
      }
      alerts_.clear("not-fluoroscopy");
      // Does the picture still lie where the mapping says? (Cheap enough every few seconds.)
      if (analysis_start - last_mapping_check >= options_.video_mapping_check) {
        last_mapping_check = analysis_start;
        const std::string misfit = geometry::video_mapping_misfit(wrap(a->frame), *field.mapping);
        misfits_in_a_row = misfit.empty() ? 0 : misfits_in_a_row + 1;
        {
          std::lock_guard lock(stats_mutex_);
          ++stats_.video_mapping_checks;
          if (!misfit.empty()) {
            ++stats_.video_mapping_misfits;
            stats_.last_video_mapping_misfit = misfit;
          }
        }
        if (misfits_in_a_row >= 2)
          alerts_.set("video-mapping", "VIDEO MAPPING DOES NOT FIT: " + misfit + "; the roadmap may be misplaced (evarnode calibrate-video)",
                      std::nullopt);
        else if (misfit.empty())
          alerts_.clear("video-mapping");
      }
    }
    // The bones: the first frame of each view goes to the pelvis thread.
    if (pelvis_.active() && !(last_bone_view && same_bone_view(*last_bone_view, a->view, options_.pelvis))) {
      last_bone_view = a->view;
      bone_views_.push({detector.clone(), a->view,
                        "frame " + std::to_string(a->frame.sequence) + ", " +
                            angulation_text(a->view.view.primary_angle_deg, a->view.view.secondary_angle_deg)});
    }
    FrameAnalysis r = analyse_frame(detector, a->view, field.candidate);
    const double waited_ms = ms_between(a->frame.host_arrival, analysis_start), took_ms = ms_between(analysis_start, Clock::now());
    {
      std::lock_guard lock(stats_mutex_);
      ++stats_.analysed;
      stats_.candidates += r.candidate ? 1 : 0;
    }
    if (!r.candidate) {
      log().debug("frame {}: no candidate: {}", a->frame.sequence, r.reason);
      continue;
    }
    ViewCandidate c{a->frame.sequence, steady_ns(a->frame.host_arrival), a->view, std::move(r.curve.points)};
    if (std::optional<ViewPair> pair = selector.add(std::move(c))) {
      log().info("view pair: frames {} and {}, {:.0f}° apart: adapting (the second view waited {:.0f} ms and was "
                 "segmented in {:.0f} ms)",
                 pair->earlier.frame, pair->later.frame, pair->separation_deg, waited_ms, took_ms);
      pairs_.put(PairJob{std::move(*pair), false});
      std::lock_guard lock(stats_mutex_);
      ++stats_.pairs;
    }
  }
}

namespace {

// A TurnStreak over views (or view pairs): one the streak holds already, seen again, adds
// nothing (the same evidence twice).
template <class Evidence>
class EvidenceStreak {
 public:
  using Same = std::function<bool(const Evidence&, const Evidence&)>;
  EvidenceStreak(int needed, Same same) : streak_(needed), same_(std::move(same)) {}
  // TurnStreak::suspect, for the evidence `e`.
  std::vector<PictureTurn> suspect(const std::vector<PictureTurn>& candidates, const Evidence& e) {
    if (std::any_of(held_.begin(), held_.end(), [&](const Evidence& h) { return same_(h, e); })) return {};
    std::vector<PictureTurn> said = streak_.suspect(candidates);
    if (streak_.length() == 1) held_.clear();
    held_.push_back(e);
    return said;
  }
  void confirm() {
    streak_.confirm();
    held_.clear();
  }
  bool suspecting() const { return streak_.length() > 0; }

 private:
  TurnStreak streak_;
  Same same_;
  std::vector<Evidence> held_;  // what made the streak
};

// Two pairs of the same two views (either way round).
bool same_views(const ViewPair& a, const ViewPair& b, const PelvisTrackingOptions& o) {
  const auto same = [&](const ViewCandidate& x, const ViewCandidate& y) { return same_bone_view(x.geometry, y.geometry, o); };
  return (same(a.earlier, b.earlier) && same(a.later, b.later)) || (same(a.earlier, b.later) && same(a.later, b.earlier));
}

}  // namespace

void LiveNode::Impl::count_orientation_check(const std::string& misfit, const std::string& alert) {
  std::lock_guard lock(stats_mutex_);
  ++stats_.orientation_checks;
  if (!misfit.empty()) {
    ++stats_.orientation_misfits;
    stats_.last_orientation_misfit = misfit;
  }
  if (!alert.empty()) {
    ++stats_.orientation_alerts;
    stats_.last_orientation_alert = alert;
  }
}

const geometry::VideoMapping* LiveNode::Impl::shown_through() const {
  // Under zoom modes each mode turns the picture its own way too: turns are said as the
  // detector's.
  return options_.video_mapping && options_.zoom_modes.empty() ? &*options_.video_mapping : nullptr;
}

std::string LiveNode::Impl::orientation_alert(const std::vector<PictureTurn>& turns, bool name_fix,
                                              std::string& why) const {
  const geometry::VideoMapping* through = shown_through();
  std::string title = "turned or mirrored";
  if (turns.size() > 1 || !name_fix) {
    why += "; it reads right with the picture shown";
    for (std::size_t k = 0; k < turns.size(); ++k)
      why += (k == 0 ? " " : k + 1 == turns.size() ? " or " : ", ") + turn_text(shown_turn(turns[k], through));
    why += ": check the display's turn and mirror";
  } else {
    title = turn_text(shown_turn(turns.front(), through));
    // Under a display mapping alone, what to set.
    if (through)
      if (const auto fixed = mapping_with_turn(*through, turns.front(), options_.detector.cols, options_.detector.rows))
        why += fmt::format("; node.json's video_mapping would need \"mirror\": {}, \"rotation_deg\": {} (it has {}, {})",
                           fixed->mirror, fixed->rotation_deg, through->mirror, through->rotation_deg);
  }
  std::transform(title.begin(), title.end(), title.begin(), [](unsigned char ch) { return std::toupper(ch); });
  return "PICTURE " + title + "? " + why + " (evarnode calibrate-video)";
}

void LiveNode::Impl::adaptation_loop() {
  // The models the model on screen was bent from (only this thread publishes): a later
  // adaptation warm-starts from it only when it bends the same ones.
  std::shared_ptr<const PelvisMovedModels> published_with;
  // Is the picture the right way round? Where the bones are not looked at (the pelvis
  // thread's check is the surer one), checked on each new pair once its model is shown (or
  // refused); said at the first pair that lies far outside the vessels as taken and in
  // them turned (check_picture_orientation: the device misses them by centimetres, which
  // a device the right way round does not); cleared by a pair that lies in them only as
  // taken. A device may read into symmetric vessels under more than one turn: the turns are
  // named, no fix. (Only views of other angles can be more decisive: a streak of two would
  // wait for a third view.)
  EvidenceStreak<ViewPair> streak(1, [this](const ViewPair& a, const ViewPair& b) { return same_views(a, b, options_.pelvis); });
  const auto check_orientation = [&](const deform::SceneDeformer& deformer, const ViewPair& pair) {
    OrientationCheck c =
        check_picture_orientation(deformer, pair, options_.adaptation, streak.suspecting(), shown_through());
    const std::vector<PictureTurn> said = c.better ? streak.suspect(c.candidates, pair) : std::vector<PictureTurn>{};
    const std::string alert = said.empty() ? std::string() : orientation_alert(said, false, c.problem);
    count_orientation_check(c.better ? "frames " + std::to_string(pair.earlier.frame) + "+" +
                                           std::to_string(pair.later.frame) + ": " + c.problem
                                     : std::string(),
                            alert);
    if (log().should_log(spdlog::level::debug)) {
      std::string tried;
      for (const auto& t : c.tried) tried += fmt::format("; {} {:.1f} mm", turn_text(t.turn), t.outside_mm);
      log().debug("picture orientation, frames {}+{}: device {:.1f} mm outside the vessels as taken{}",
                  pair.earlier.frame, pair.later.frame, c.as_set.outside_mm, tried);
    }
    if (c.better) {
      log().warn("frames {}+{}: {}", pair.earlier.frame, pair.later.frame, c.problem);
      if (!said.empty()) alerts_.set("picture-orientation-device", alert, std::nullopt);
      return;
    }
    if (!c.confirmed) return;  // a device that bends its vessels far, or none: undecided
    streak.confirm();
    alerts_.clear("picture-orientation-device");
  };
  while (std::optional<PairJob> job = pairs_.take()) {
    const ViewPair& pair = job->pair;
    const bool again = job->again;
    adapting_.store(true);
    struct Done {
      std::atomic<bool>& flag;
      bool released = false;
      void release() {
        if (released) return;
        released = true;
        flag.store(false);
        flag.notify_all();
      }
      ~Done() { release(); }
    } done{adapting_};
    // The models as registered or as the pelvis moved them.
    std::shared_ptr<const PelvisMovedModels> moved;
    {
      std::lock_guard lock(moved_mutex_);
      moved = moved_;
      adapting_pair_ = true;
    }
    // Done: if the models moved meanwhile, the pair on screen (this one if it was used) is
    // adapted again from them.
    const auto finished = [&](bool used) {
      std::optional<ViewPair> once_more;
      {
        std::lock_guard lock(moved_mutex_);
        adapting_pair_ = false;
        if (used) shown_pair_ = pair;
        if (moved_ != moved) once_more = shown_pair_;
      }
      if (once_more) adapt_again(std::move(*once_more));
    };
    try {
      const auto shown = model();
      auto m = std::make_shared<const AdaptedModel>(
          adapt_model(moved ? *moved->deformer : *deformer_, pair, options_.adaptation,
                      shown->adapted && published_with == moved ? &shown->adapted->deformation : nullptr));
      publish(m, moved ? std::make_shared<const geometry::PelvisRegistration>(moved->pose) : nullptr);
      published_with = moved;
      const double ready_ms = static_cast<double>(steady_ns(Clock::now()) - pair.later.time_ns) * 1e-6;
      const auto& contained = m->deformation.containment;
      const bool outside = deform::leaves_device_outside(contained);
      {
        std::lock_guard lock(stats_mutex_);
        ++stats_.adaptations;
        stats_.last_failure.clear();
        if (!again) adaptation_latencies_.add(ready_ms);  // the second view's wait, which a pair once more is not
        stats_.models_device_outside += outside ? 1 : 0;
        stats_.last_device_outside_length_mm = contained.outside_length_mm;
        stats_.last_device_outside_max_depth_mm = contained.outside_max_depth_mm;
      }
      if (!again) {  // the selector hears of the pairs it formed
        std::lock_guard lock(outcome_mutex_);
        pair_outcome_ = PairOutcome{true, pair.earlier.id()};
      }
      alerts_.clear("adaptation");
      // Shown, since it is still closer to the anatomy than the preoperative one, but said.
      if (outside) {
        const std::string what = deform::describe_outside(contained);
        log().warn("model from frames {}+{}: {}", m->frame_earlier, m->frame_later, what);
        alerts_.set("device-outside", "adapted roadmap: " + what, std::nullopt);
      } else {
        alerts_.clear("device-outside");
      }
      log().info("adapted model from frames {}+{}{}: device {} points, residual {:.2f} px; reconstruction {:.1f} ms, "
                 "deformation {:.1f} ms; {}",
                 m->frame_earlier, m->frame_later, moved ? " (models moved with the pelvis)" : "",
                 m->reconstruction.points.size(), m->reconstruction.mean_residual_px, m->reconstruct_ms, m->deform_ms,
                 again ? std::string("the same views adapted again")
                       : fmt::format("ready {:.0f} ms after the second view arrived", ready_ms));
      if (log().should_log(spdlog::level::debug))
        for (const auto& r : m->deformation.reports)
          log().debug("  {}: {}; {} handles, {} constrained; {} iterations in {} round(s){}; {:.1f} ms", r.name, r.role,
                      r.control_points, r.constrained_vertices, r.iterations, r.rounds,
                      r.converged ? "" : " (NOT converged)",
                      r.timings.control_points_ms + r.timings.factor_ms + r.timings.iterate_ms);
      finished(true);
    } catch (const std::exception& e) {
      {
        std::lock_guard lock(stats_mutex_);
        ++stats_.adaptation_failures;
        stats_.last_failure = "frames " + std::to_string(pair.earlier.frame) + "+" + std::to_string(pair.later.frame) +
                              ": " + e.what();
      }
      if (!again) {
        std::lock_guard lock(outcome_mutex_);
        pair_outcome_ = PairOutcome{false, pair.earlier.id()};
      }
      alerts_.set("adaptation", std::string("frames ") + std::to_string(pair.earlier.frame) + "+" +
                                  std::to_string(pair.later.frame) + ": " + e.what() + "; last good model kept",
                options_.alert_hold);
      finished(false);
    }
    // The frames go on being analysed while the picture's orientation is checked.
    done.release();
    if (!again && !pelvis_.active()) {
      try {
        check_orientation(moved ? *moved->deformer : *deformer_, pair);
      } catch (const std::exception& e) {
        log().error("picture orientation, frames {}+{}: {}", pair.earlier.frame, pair.later.frame, e.what());
      }
    }
  }
}

void LiveNode::Impl::adapt_again(ViewPair pair) {
  // Not over a newer pair waiting: that one bends the moved models anyway.
  {
    std::lock_guard lock(stats_mutex_);
    ++stats_.readaptations;
  }
  if (pairs_.put_if_empty(PairJob{std::move(pair), true})) {
    log().info("pelvis: the model on screen is adapted again from the moved models");
  } else {
    std::lock_guard lock(stats_mutex_);
    --stats_.readaptations;
  }
}

void LiveNode::Impl::pelvis_loop() {
  const auto pose_text = [](const geometry::PelvisRegistration& r) {
    return fmt::format("{:.1f} mm, {:.1f}° from the registration", r.shift_mm.norm(),
                       r.turn_deg());
  };
  // Is the picture the right way round? Each view's bones, as taken and turned: said when
  // two different views in a row match only turned alike, cleared by a view that matches
  // only as taken.
  std::optional<geometry::RayCaster> bones;
  EvidenceStreak<FrameView> streak(
      2, [this](const FrameView& a, const FrameView& b) { return same_bone_view(a, b, options_.pelvis); });
  const auto check_orientation = [&](const BoneView& b) {
    if (!bones) bones.emplace(deformer_->scene().pelvis);
    BoneOrientationCheck c = check_bone_orientation(*bones, {b.view.P_ct, b.detector, b.name},
                                                    options_.pelvis.registration, 0.15, shown_through());
    const std::vector<PictureTurn> said = c.better ? streak.suspect(c.candidates, b.view) : std::vector<PictureTurn>{};
    const std::string alert = said.empty() ? std::string() : orientation_alert(said, true, c.problem);
    count_orientation_check(c.better ? c.problem : std::string(), alert);
    if (log().should_log(spdlog::level::debug)) {
      std::string tried;
      for (const auto& [t, m] : c.tried) tried += fmt::format("; {} {:.2f}", turn_text(t), m.correlation);
      log().debug("picture orientation, {}: the bones match with a gradient correlation of {:.2f} as taken{}", b.name,
                  c.as_set.correlation, tried);
    }
    if (c.better) {
      log().warn("{}", c.problem);
      if (!said.empty()) alerts_.set("picture-orientation-bones", alert, std::nullopt);
    } else if (c.confirmed) {
      streak.confirm();
      alerts_.clear("picture-orientation-bones");
    }
  };
  // The pelvis registered in the views kept, and the models moved with it.
  const auto track = [&](const BoneView& b) {
    std::string status;
    std::optional<geometry::PelvisRegistration> found;
    std::shared_ptr<const PelvisMovedModels> now_moved;
    try {
      if (!pelvis_.offer(b.detector, b.view, b.name)) {
        std::lock_guard lock(stats_mutex_);
        stats_.pelvis_views = pelvis_.views();
        return;
      }
      const auto t0 = Clock::now();
      found = pelvis_.register_views();
      const bool moves = pelvis_.moves_models(*found);
      log().info("pelvis {} (registered in {:.0f} ms{})", describe(*found), ms_between(t0, Clock::now()),
                 moves ? "; the models move with it" : "");
      for (const auto& v : found->views)
        if (!v.used) log().info("pelvis: view {} not used: {}", v.name, v.reason);
      if (moves) {
        try {
          now_moved = pelvis_.move_models(*found);
          log().info("pelvis: models moved with it and prepared in {:.0f} ms", now_moved->deformer->precompute_ms());
        } catch (const std::exception& e) {
          status = "found, but the models cannot move with it (see the log)";
          log().warn("pelvis {}, but the models cannot move with it: {}; they stay as they were", describe(*found), e.what());
        }
      }
    } catch (const std::exception& e) {
      // Whatever the registration met (memory, an image it could not read): said, and the
      // node goes on with the models as they are.
      status = "not looked for in this view: it failed (see the log)";
      log().error("pelvis: {}: {}; the models stay as they are", b.name, e.what());
    }
    const std::shared_ptr<const PelvisMovedModels> moved = now_moved ? now_moved : moved_models();
    if (status.empty() && found)
      status = !found->found ? (moved ? "not found again (see the log); models moved as found before: " + pose_text(moved->pose)
                                      : "not found (see the log); models where the registration put them")
               : moved       ? pose_text(*found) + "; models moved with it"
                             : pose_text(*found) + "; models where the registration put them (within " +
                                   fmt::format("{:.1f}", options_.pelvis.remake_mm) + " mm)";
    {
      std::lock_guard lock(stats_mutex_);
      stats_.pelvis_views = pelvis_.views();
      stats_.pelvis_registrations += found ? 1 : 0;
      stats_.pelvis_found += found && found->found ? 1 : 0;
      stats_.pelvis_moves += now_moved ? 1 : 0;
      if (found) stats_.last_pelvis = describe(*found);
      stats_.pelvis_status = status;
      if (moved) {
        stats_.pelvis_shift_mm = {moved->pose.shift_mm.x(), moved->pose.shift_mm.y(), moved->pose.shift_mm.z()};
        stats_.pelvis_turn_deg = moved->pose.turn_deg();
      }
    }
    if (!now_moved) return;
    // The model on screen was bent from where the models were: its pair is adapted again from
    // where they are now, here when no adaptation runs, else by the adaptation thread when
    // it is done.
    std::optional<ViewPair> once_more;
    {
      std::lock_guard lock(moved_mutex_);
      moved_ = now_moved;
      if (!adapting_pair_) once_more = shown_pair_;
    }
    if (once_more) adapt_again(std::move(*once_more));
  };
  for (;;) {
    std::optional<BoneView> b = bone_views_.pop(std::chrono::milliseconds(100));
    if (stopping_.load()) break;  // what is left is not registered: the node stops
    if (!b) {
      if (bone_views_.closed()) break;
      continue;
    }
    track(*b);  // the pelvis first: the models wait for it
    try {
      check_orientation(*b);
    } catch (const std::exception& e) {
      log().error("picture orientation: {}: {}", b->name, e.what());
    }
  }
}

std::shared_ptr<const PelvisMovedModels> LiveNode::Impl::moved_models() const {
  std::lock_guard lock(moved_mutex_);
  return moved_;
}

void LiveNode::Impl::publish(std::shared_ptr<const AdaptedModel> adapted,
                             std::shared_ptr<const geometry::PelvisRegistration> pelvis) {
  auto roadmap = std::make_shared<overlay::RoadmapModel>(*initial_roadmap_);
  show_adapted(*roadmap, *adapted);
  auto m = std::make_shared<PublishedModel>();
  m->adapted = std::move(adapted);
  m->pelvis = std::move(pelvis);
  m->roadmap = std::move(roadmap);
  m->ready = Clock::now();
  std::lock_guard lock(model_mutex_);
  m->version = model_->version + 1;
  model_ = std::move(m);
}

void LiveNode::Impl::output_loop() {
  // The sinks hear of every model, the preoperative one (version 0) included.
  std::uint64_t shown_version = std::numeric_limits<std::uint64_t>::max();
  std::vector<std::string> last_error(sinks_.size());
  const auto guarded = [&](std::size_t i, const auto& call) {
    try {
      call(*sinks_[i]);
      last_error[i].clear();
    } catch (const std::exception& e) {
      {
        std::lock_guard lock(stats_mutex_);
        ++stats_.sink_errors;
      }
      if (last_error[i] != e.what()) log().error("output {}: {} (the node goes on)", sinks_[i]->name(), e.what());
      last_error[i] = e.what();
    }
  };
  for (;;) {
    std::optional<ComposedFrame> f = output_.pop(std::chrono::milliseconds(100));
    if (!f) {
      if (output_.closed()) break;
      continue;
    }
    if (f->model && f->model->version != shown_version) {
      shown_version = f->model->version;
      for (std::size_t i = 0; i < sinks_.size(); ++i) guarded(i, [&](OutputSink& s) { s.model_changed(*f->model); });
    }
    for (std::size_t i = 0; i < sinks_.size(); ++i) guarded(i, [&](OutputSink& s) { s.write(*f); });
  }
  for (std::size_t i = 0; i < sinks_.size(); ++i) guarded(i, [&](OutputSink& s) { s.finish(); });
}

NodeStatistics LiveNode::Impl::statistics() const {
  std::optional<std::uint64_t> lost;  // the source's own count, while the node has one
  {
    std::lock_guard lock(source_mutex_);
    if (frames_ != nullptr) lost = frames_->statistics().dropped;
  }
  NodeStatistics s;
  std::vector<double> latencies, adaptation;
  {
    std::lock_guard lock(stats_mutex_);
    s = stats_;
    latencies = latencies_.values();
    adaptation = adaptation_latencies_.values();
  }
  // Sorted outside the lock: the compose thread takes it for every frame.
  s.latency_ms = percentiles(std::move(latencies));
  s.adaptation_ms = percentiles(std::move(adaptation));
  s.dropped_input = input_.dropped();
  s.dropped_output = output_.dropped();
  s.analysis_skipped = analysis_.superseded() + s.analysis_replaced;
  s.pairs_superseded = pairs_.superseded();
  if (lost) s.frames_lost_by_source = *lost;
  {
    std::lock_guard tl(timeline_mutex_);
    s.carm_clock_offset_ns = timeline_.carm_clock_offset_ns();
  }
  return s;
}

std::shared_ptr<const PublishedModel> LiveNode::Impl::model() const {
  std::lock_guard lock(model_mutex_);
  return model_;
}

LiveNode::LiveNode(const geometry::Scene& scene, NodeOptions options, std::vector<std::unique_ptr<OutputSink>> sinks)
    : impl_(std::make_unique<Impl>(scene, std::move(options), std::move(sinks))) {}
LiveNode::~LiveNode() = default;
void LiveNode::start(acquisition::FrameSource& frames, acquisition::CArmGeometrySource& carm) { impl_->start(frames, carm); }
void LiveNode::stop() { impl_->stop(); }
void LiveNode::set_mode(overlay::RoadmapMode mode) { impl_->set_mode(mode); }
overlay::RoadmapMode LiveNode::mode() const { return impl_->mode(); }
NodeStatistics LiveNode::statistics() const { return impl_->statistics(); }
std::shared_ptr<const PublishedModel> LiveNode::model() const { return impl_->model(); }

}  // namespace evar::node
