#pragma once
// What the live node is told: the detector, the registration, how frames become
// candidates, views become pairs and pairs become models, how the roadmap is drawn, and
// the health limits and queue sizes. Checked in one place, check_options(), which
// LiveNode's constructor calls.
#include <Eigen/Core>
#include <chrono>
#include <cstddef>
#include <optional>
#include <vector>

#include "evar/acquisition/frame_loss_monitor.hpp"
#include "evar/acquisition/geometry_timeline.hpp"
#include "evar/deform/scene_deformation.hpp"
#include "evar/geometry/detector.hpp"
#include "evar/geometry/video_mapping.hpp"
#include "evar/geometry/zoom_mode.hpp"
#include "evar/node/device_candidate.hpp"
#include "evar/node/model_adaptation.hpp"
#include "evar/node/pelvis_tracker.hpp"
#include "evar/node/view_pair_selector.hpp"
#include "evar/overlay/frame_compositor.hpp"

namespace evar::node {

struct NodeOptions {
  geometry::DetectorSpec detector;                 ///< the frames' detector (size checked per frame)
  /// The C-arm's zoom modes (issue 31; node.json "zoom_modes"). Given, `detector` is the
  /// physical detector and a frame is the image of the mode it was taken in: the one the
  /// C-arm link says (CArmPose::zoom_mode), or `zoom_mode`. A mode not listed, or none said
  /// with several listed, leaves the frame without a roadmap and says why on screen.
  std::vector<geometry::ZoomMode> zoom_modes;
  /// Not 0: every frame is taken in this mode of `zoom_modes`, whatever the link says (a link
  /// without a zoom readout).
  int zoom_mode = 0;
  /// Set: the frames are the C-arm's video output, the detector image shown in a rectangle
  /// of them (issue 31). Frames must have its video size; the analysis reads the detector
  /// image out of them and the roadmap is drawn through it; frames keep their video size.
  std::optional<geometry::VideoMapping> video_mapping;
  /// Under a video mapping, an analysed frame is checked this often for image content past
  /// the mapping's image rectangle (geometry::video_mapping_misfit); two misfits in a row
  /// raise an alert until a check fits again (the monitor's layout or zoom changed, or the
  /// mapping was wrong): the roadmap may be misplaced.
  std::chrono::milliseconds video_mapping_check{2000};
  Eigen::Matrix4d registration = Eigen::Matrix4d::Identity();  ///< CT → C-arm at table 0
  CandidateOptions candidate;
  ViewPairOptions pairs;
  AdaptationOptions adaptation;
  deform::DeformOptions deform;
  /// The pelvis found in the analysed frames where the scene has its bones, and the models
  /// moved with it before they are bent (node/pelvis_tracker.hpp); on its own thread.
  PelvisTrackingOptions pelvis;
  /// The roadmap layer is drawn in the background: no frame waits for a new view's or model's layer.
  overlay::CompositorOptions compositor{.supersample = 2, .window_level = {}, .layer_in_background = true};
  overlay::RoadmapMode mode = overlay::RoadmapMode::Both;
  acquisition::GeometryTimelineOptions timeline;
  /// Frames' device_time_ns is on the C-arm's clock (a replayed session: one recording clock
  /// for both), so each frame's geometry is looked up at it instead of through the estimated
  /// host-to-C-arm offset, which a replay faster or slower than recorded would not fit.
  bool frames_on_carm_clock = false;
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

/// std::invalid_argument "node options: <field>: <what is wrong>" for the first field that
/// no node could run with (a detector without a size, a registration that is not rigid, a
/// duration or queue of 0, a share outside 0..1, the pairing and frame-loss options their
/// own checks refuse). The deformation's options are checked by the SceneDeformer.
void check_options(const NodeOptions& options);

}  // namespace evar::node
