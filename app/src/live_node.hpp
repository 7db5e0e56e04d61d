#pragma once
// The live node (`evarnode run`): frames and C-arm states from acquisition's interfaces
// (hardware or a replayed session) in, composited roadmap frames out to the sinks.
//
//   source thread   → input queue (4, oldest dropped) →
//   compose thread  : the frame's layout checked, geometry at the frame's time
//                     (GeometryTimeline), roadmap composited with the current model,
//                     status block; eligible frames (beam on, C-arm still, geometry fresh)
//                     offered to analysis (latest only)
//                   → output queue (8, oldest dropped) → output thread → sinks
//   analysis thread : device segmentation, candidates, view pairs → adaptation (latest only)
//   adaptation thread: reconstruction and deformation; the new model is published and the
//                     compositor switches to it on the next frame
//
// Nothing waits on the deformation, and no queue grows without bound: every drop is
// counted. Health (a stalled or lost source, stale geometry, a failed adaptation) goes to
// the log when it changes and onto the frames while it lasts; the last good model stays.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "evar/acquisition/carm_geometry_source.hpp"
#include "evar/acquisition/frame_loss_monitor.hpp"
#include "evar/acquisition/frame_source.hpp"
#include "evar/acquisition/geometry_timeline.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/overlay/frame_compositor.hpp"
#include "mailbox.hpp"
#include "model_adaptation.hpp"
#include "device_candidate.hpp"

namespace evar::app {

struct NodeOptions {
  sim::DetectorSpec detector;                 ///< the frames' detector (size checked per frame)
  Eigen::Matrix4d registration = Eigen::Matrix4d::Identity();  ///< CT → C-arm at table 0
  CandidateOptions candidate;
  ViewPairOptions pairs;
  AdaptationOptions adaptation;
  deform::DeformOptions deform;
  /// The roadmap layer is drawn in the background: no frame waits for a new view's or model's layer.
  overlay::CompositorOptions compositor{.supersample = 2, .window_level = {}, .layer_in_background = true};
  overlay::RoadmapMode mode = overlay::RoadmapMode::Both;
  acquisition::GeometryTimelineOptions timeline;
  std::chrono::milliseconds video_stall{1000};  ///< no frame for this long: "no video"
  /// The source losing this share of its frames or more (a GigE link dropping packets,
  /// a grabber dropping buffers) is an alert while it lasts: the image is live but jerky.
  acquisition::FrameLossOptions frame_loss;
  /// While there is no video the last frame is shown again this often, marked "LAST IMAGE
  /// HELD" (ComposedFrame::held), so the screen says so and the window answers keys.
  std::chrono::milliseconds held_frame_interval{250};
  std::chrono::milliseconds alert_hold{5000};   ///< a failed adaptation stays on screen this long
  /// A C-arm link notice (bad frames on a line that still delivers, a warning the C-arm
  /// sent) stays on screen this long: longer than the links' 10 s between notices, so a
  /// line that stays noisy keeps its alert up rather than flickering it.
  std::chrono::milliseconds carm_notice_hold{15000};
  std::size_t input_queue = 4, output_queue = 8;
  /// Make the source wait when the input queue is full instead of dropping the oldest frame:
  /// for replays, whose source can wait; live sources cannot.
  bool backpressure = false;
};

/// A model the node adapted, with the roadmap drawn from it.
struct PublishedModel {
  std::uint64_t version = 0;                     ///< 0 = the preoperative model
  std::shared_ptr<const AdaptedModel> adapted;   ///< null for version 0
  std::shared_ptr<const overlay::RoadmapModel> roadmap;
  std::chrono::steady_clock::time_point ready;
};

struct ComposedFrame {
  std::shared_ptr<const overlay::Image> image;    ///< shared, so a sink may keep it without a copy
  std::uint64_t sequence = 0;
  std::int64_t device_time_ns = 0;
  double latency_ms = 0.0;                        ///< arrival → composited
  std::optional<geometry::ProjectionMatrix> P_ct; ///< the frame's projection; empty: no usable geometry (none drawn)
  /// What the frame shows of the roadmap: `model`'s (Current), the previous model's while
  /// `model`'s layer is drawn, or none (no geometry, or a new view's layer not ready yet).
  overlay::RoadmapShown roadmap = overlay::RoadmapShown::None;
  double mm_per_px = 0.0;                         ///< at the isocenter, with P_ct
  std::shared_ptr<const PublishedModel> model;
  overlay::StatusBlock status;                    ///< the text drawn on the frame: state lines and alerts
  /// The last frame shown again while there is no video (NodeOptions::held_frame_interval):
  /// for the screen and Slicer, not a new picture (the video file and snapshots skip it).
  bool held = false;
};

/// Where composited frames go: a window, a video file, snapshots, OpenIGTLink. Called on
/// the output thread only; an exception is logged and counted, and the node goes on.
class OutputSink {
 public:
  virtual ~OutputSink() = default;
  virtual std::string name() const = 0;
  virtual void write(const ComposedFrame& frame) = 0;
  /// A new model was published (called before the first frame that shows it).
  virtual void model_changed(const PublishedModel&) {}
  /// The node is stopping: flush and close.
  virtual void finish() {}
};

struct Percentiles {
  double p50 = 0, p99 = 0, max = 0;
  std::size_t n = 0;
};

struct NodeStatistics {
  std::uint64_t frames_in = 0, frames_composited = 0, frames_with_roadmap = 0;
  std::uint64_t dropped_input = 0, dropped_output = 0, frames_lost_by_source = 0;
  std::uint64_t frames_wrong_size = 0;
  std::uint64_t frames_held = 0;     ///< the last frame shown again while there was no video (not in frames_composited)
  /// Frames and pairs handed on but never analysed or adapted: replaced by a newer one, or
  /// left when the node stopped (so pairs = adaptations + adaptation_failures + pairs_superseded).
  std::uint64_t analysed = 0, analysis_skipped = 0, candidates = 0, pairs = 0, pairs_superseded = 0;
  std::uint64_t analysis_waited = 0;  ///< frames whose analysis waited for an adaptation to finish
  std::uint64_t analysis_replaced = 0;  ///< of those, frames skipped for a newer one (in analysis_skipped)
  std::uint64_t adaptations = 0, adaptation_failures = 0;
  std::uint64_t video_stalls = 0, stale_geometry_frames = 0, moving_frames = 0, sink_errors = 0;
  std::uint64_t frame_loss_alerts = 0;  ///< times the source began losing frames (NodeOptions::frame_loss)
  std::uint64_t carm_notices = 0;       ///< the C-arm link's news: bad frames, the C-arm's warnings
  std::string last_carm_notice;
  Percentiles latency_ms;            ///< frame arrival → composited, over the last kLatencyWindow frames
  Percentiles adaptation_ms;         ///< second view's frame arrival → model ready, over the last kLatencyWindow adaptations
  std::string last_failure;          ///< the last adaptation failure ("" if none)
  std::optional<std::int64_t> carm_clock_offset_ns;
};

class LiveNode {
 public:
  /// The scene must outlive the node. Throws geometry::InputError for a scene the
  /// deformation cannot use, std::invalid_argument for bad options.
  LiveNode(const geometry::Scene& scene, NodeOptions options, std::vector<std::unique_ptr<OutputSink>> sinks);
  ~LiveNode();
  LiveNode(const LiveNode&) = delete;
  LiveNode& operator=(const LiveNode&) = delete;

  /// Latency percentiles are over this many most recent frames (about 55 min at 30 fps).
  static constexpr std::size_t kLatencyWindow = 100'000;

  /// Starts the threads and the sources (C-arm first). The sources must outlive stop().
  /// Throws what the sources throw when they cannot be opened (nothing left running). A node
  /// runs once: starting it again after stop() throws std::logic_error (its queues are closed).
  void start(acquisition::FrameSource& frames, acquisition::CArmGeometrySource& carm);
  /// Stops the sources, lets the queued frames through, waits for a running adaptation,
  /// finishes the sinks, and lets go of the sources (statistics() keeps their last counts).
  /// Idempotent.
  void stop();

  void set_mode(overlay::RoadmapMode mode) { mode_.store(mode); }
  overlay::RoadmapMode mode() const { return mode_.load(); }
  NodeStatistics statistics() const;
  std::shared_ptr<const PublishedModel> model() const;

 private:
  struct Analysis {  // a frame offered to the analysis thread
    acquisition::Frame frame;
    FrameView view;
  };
  void on_frame(const acquisition::Frame& frame);
  void compose_loop();
  void analysis_loop();
  void adaptation_loop();
  void output_loop();
  void publish(std::shared_ptr<const AdaptedModel> adapted);
  /// hold: the alert clears itself after this long (a passing event); none: it stays until
  /// clear_alert (a condition). Logged when its text changes or it comes back after expiring.
  void set_alert(const std::string& key, const std::string& text, std::optional<std::chrono::milliseconds> hold);
  /// Samples the source's counts (compose thread) and raises or clears the frame-loss alert.
  void watch_frame_loss(acquisition::FrameLossMonitor& monitor);
  void clear_alert(const std::string& key);
  std::vector<std::string> current_alerts(std::string_view except = {});

  NodeOptions options_;
  std::vector<std::unique_ptr<OutputSink>> sinks_;
  std::unique_ptr<deform::SceneDeformer> deformer_;
  std::shared_ptr<const overlay::RoadmapModel> initial_roadmap_;
  std::atomic<overlay::RoadmapMode> mode_;

  mutable std::mutex source_mutex_;  // frames_ against stop() letting go of it
  acquisition::FrameSource* frames_ = nullptr;  // null when not running
  acquisition::CArmGeometrySource* carm_ = nullptr;
  BoundedQueue<acquisition::Frame> input_;
  BoundedQueue<ComposedFrame> output_;
  LatestSlot<Analysis> analysis_;
  LatestSlot<ViewPair> pairs_;
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
  std::deque<double> latencies_;  // the last kLatencyWindow frames
  std::deque<double> adaptation_latencies_;  // the last kLatencyWindow adaptations

  struct Alert {
    std::string text;
    std::chrono::steady_clock::time_point until;  // max() = until cleared
  };
  std::mutex alerts_mutex_;
  std::vector<std::pair<std::string, Alert>> alerts_;

  std::thread compose_thread_, analysis_thread_, adaptation_thread_, output_thread_;
  bool running_ = false;
  bool started_ = false;  // once: a stopped node's queues stay closed
};

/// p50/p99/max of a sample (nearest rank); zeros for none.
Percentiles percentiles(std::vector<double> values);

}  // namespace evar::app
