#pragma once
// The pelvis found in the frames the node analyses (issue 28; docs/DEFORMATION.md, "The
// pelvis"). The models are registered to the renal arteries; the pelvis, and the iliacs it
// holds, may lie elsewhere on the table, and its bones show in every fluoroscopy frame. The
// first frame of each view of the bones is kept; from the second view on, the pelvis is
// registered in all views kept (geometry::register_pelvis), and when it lies elsewhere than
// the models were last moved to, the scene is moved with it (deform::pelvis_shift_for) and
// a deformer made for the moved scene: the base the next adaptations bend.
//
// The same steps serve `evarnode eval` and the live node, which runs them on a thread of
// their own so that no frame and no adaptation waits for them.
#include <Eigen/Core>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "evar/deform/scene_deformation.hpp"
#include "evar/geometry/pelvis_registration.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/node/frame_view.hpp"

namespace evar::node {

struct PelvisTrackingOptions {
  /// Find the pelvis where the scene has its bones (scene.json "pelvis"); off: the models
  /// stay where the registration put them.
  bool enabled = true;
  /// Frames whose views' directions are closer than this, with the table moved by less than
  /// same_table_mm, are one view of the bones (its first frame is kept).
  double same_view_deg = 2.0;
  double same_table_mm = 5.0;
  std::size_t max_views = 8;  ///< views kept (the oldest is forgotten)
  /// The models are moved again only when a new pose moves the bones' centroid, or a point
  /// 100 mm from it by the turn, farther than this from where they were last moved to.
  double remake_mm = 0.5;
  geometry::PelvisRegistrationOptions registration;
};

/// std::invalid_argument "pelvis: <field>: <what is wrong>" for options no tracker runs with
/// (the registration's own included).
void check_options(const PelvisTrackingOptions& options);

/// Whether two frames show the bones from one view (PelvisTrackingOptions::same_view_deg
/// and same_table_mm): the table's move is read from their CT-to-C-arm transforms.
bool same_bone_view(const FrameView& a, const FrameView& b, const PelvisTrackingOptions& options);

/// The models moved with a pelvis found: the scene moved, and a deformer made for it.
/// Not movable (the deformer holds on to the scene): kept behind a pointer.
struct PelvisMovedModels {
  geometry::PelvisRegistration pose;  ///< what was found (found == true)
  geometry::Scene scene;
  std::unique_ptr<const deform::SceneDeformer> deformer;  ///< on `scene`

  PelvisMovedModels(const geometry::Scene& registered, const geometry::PelvisRegistration& found,
                    const deform::DeformOptions& options);
  PelvisMovedModels(const PelvisMovedModels&) = delete;
  PelvisMovedModels& operator=(const PelvisMovedModels&) = delete;
};

/// "found in 2 views: 8.3 mm, turned 1.2°" or "not found: <why>".
std::string describe(const geometry::PelvisRegistration& r);

class PelvisTracker {
 public:
  /// `scene` must outlive the tracker. std::invalid_argument for bad options.
  PelvisTracker(const geometry::Scene& scene, PelvisTrackingOptions options, deform::DeformOptions deform);

  /// Enabled and the scene has the pelvis's bones: frames are worth offering.
  bool active() const { return active_; }

  /// A frame of the detector (one channel, brighter where less is absorbed) from a view not
  /// kept yet is kept (copied). True when it is kept and makes two views or more: time to
  /// register(). Frames of a view kept are not (the first frame of a view stands for it),
  /// nor frames of the view of the frame offered before (a view forgotten by register_views
  /// is offered again when the C-arm comes back to it, not at its next frame).
  bool offer(const cv::Mat& detector, const FrameView& view, std::string name);
  std::size_t views() const { return views_.size(); }

  /// Registers the pelvis in the views kept (two at least, else refused). When it is
  /// refused, the views the match did not use (no bones in them, a frame that was not
  /// fluoroscopy) are forgotten, so that a later frame of theirs is offered again.
  geometry::PelvisRegistration register_views();

  /// True when `found` was found and lies farther than remake_mm from the pose the models
  /// were last moved to (none yet: the registration's).
  bool moves_models(const geometry::PelvisRegistration& found) const;

  /// The models moved with `found`, which becomes the pose they were last moved to.
  /// base::InputError when the scene cannot be moved (deform::pelvis_shift_for's reasons);
  /// then nothing changes.
  std::shared_ptr<const PelvisMovedModels> move_models(const geometry::PelvisRegistration& found);

 private:
  struct Kept {
    FrameView view;
    geometry::PelvisView bones;
  };
  const geometry::Scene& scene_;
  PelvisTrackingOptions options_;
  deform::DeformOptions deform_;
  bool active_ = false;
  std::vector<Kept> views_;
  std::optional<FrameView> last_offered_;
  Eigen::Vector3d moved_shift_mm_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d moved_rotation_ = Eigen::Matrix3d::Identity();
};

}  // namespace evar::node
