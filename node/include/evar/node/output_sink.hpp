#pragma once
// What the node hands its outputs: each composited frame with the model it shows, and
// each newly published model; and the interface every output (window, video file,
// snapshots, OpenIGTLink) implements.
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/pelvis_registration.hpp"
#include "evar/node/frame_view.hpp"
#include "evar/node/model_adaptation.hpp"
#include "evar/overlay/frame_compositor.hpp"

namespace evar::node {

/// A model the node adapted, with the roadmap drawn from it.
struct PublishedModel {
  std::uint64_t version = 0;                     ///< 0 = the preoperative model
  std::shared_ptr<const AdaptedModel> adapted;   ///< null for version 0
  std::shared_ptr<const overlay::RoadmapModel> roadmap;
  std::chrono::steady_clock::time_point ready;
  /// The pelvis's pose the adapted model's vessels were moved by before they were bent
  /// (node/pelvis_tracker.hpp); null: where the registration put them.
  std::shared_ptr<const geometry::PelvisRegistration> pelvis;
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
  /// The frame's pixel at the detector (mm; the zoom mode's imager spacing over the video
  /// scale) when its field is known; 0 when not (a zoom mode not listed).
  double detector_mm_per_px = 0.0;
  /// The detector's view behind P_ct: its projection is P_ct itself, or under a video
  /// mapping (NodeOptions::video_mapping) the one P_ct carries onto the video frame.
  std::optional<FrameView> detector_view;
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

}  // namespace evar::node
