#include "evar/node/pelvis_tracker.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include <spdlog/fmt/fmt.h>

#include "evar/deform/pelvis_shift.hpp"
#include "evar/geometry/two_view_reconstruction.hpp"

namespace evar::node {

void check_options(const PelvisTrackingOptions& o) {
  const auto bad = [](const char* field, const char* what) {
    throw std::invalid_argument(std::string("pelvis: ") + field + ": " + what);
  };
  if (!(o.same_view_deg > 0.0 && o.same_view_deg < 90.0)) bad("same_view_deg", "must lie in (0, 90)");
  if (!(o.same_table_mm > 0.0) || !std::isfinite(o.same_table_mm)) bad("same_table_mm", "must be positive");
  if (o.max_views < 2) bad("max_views", "must be 2 or more (two views fix the pelvis's depth)");
  if (!(o.remake_mm >= 0.0) || !std::isfinite(o.remake_mm)) bad("remake_mm", "must be 0 or more");
  try {
    geometry::check_options(o.registration);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("pelvis: registration: ") + e.what());
  }
}

bool same_bone_view(const FrameView& a, const FrameView& b, const PelvisTrackingOptions& options) {
  // CT → C-arm = translate(table) · registration: the translations differ by the table's move.
  const double table_mm = (a.ct_to_carm.topRightCorner<3, 1>() - b.ct_to_carm.topRightCorner<3, 1>()).norm();
  return table_mm < options.same_table_mm && geometry::view_separation_deg(a.P_ct, b.P_ct) < options.same_view_deg;
}

PelvisMovedModels::PelvisMovedModels(const geometry::Scene& registered, const geometry::PelvisRegistration& found,
                                     const deform::DeformOptions& options)
    : pose(found), scene(registered) {
  deform::apply(deform::pelvis_shift_for(registered, found.shift_mm, found.rotation, found.pivot_mm), scene);
  deformer = std::make_unique<const deform::SceneDeformer>(scene, options);
}

std::string describe(const geometry::PelvisRegistration& r) {
  if (!r.found) return "not found: " + r.refused;
  const auto used = std::count_if(r.views.begin(), r.views.end(), [](const auto& v) { return v.used; });
  return fmt::format("found in {} of {} views: moved {:.1f} mm{}", used, r.views.size(), r.shift_mm.norm(),
                     r.turned ? fmt::format(", turned {:.1f}°", r.turn_deg()) : std::string(" (translation only)"));
}

PelvisTracker::PelvisTracker(const geometry::Scene& scene, PelvisTrackingOptions options, deform::DeformOptions deform)
    : scene_(scene), options_((check_options(options), std::move(options))), deform_(std::move(deform)),
      active_(options_.enabled && scene.pelvis.V.rows() > 0 && scene.pelvis.F.rows() > 0) {}

bool PelvisTracker::offer(const cv::Mat& detector, const FrameView& view, std::string name) {
  if (!active_) return false;
  const bool same_as_last = last_offered_ && same_bone_view(*last_offered_, view, options_);
  last_offered_ = view;
  if (same_as_last) return false;
  if (std::any_of(views_.begin(), views_.end(), [&](const Kept& k) { return same_bone_view(k.view, view, options_); }))
    return false;
  views_.push_back({view, {view.P_ct, detector.clone(), std::move(name)}});
  if (views_.size() > options_.max_views) views_.erase(views_.begin());
  return views_.size() >= 2;
}

geometry::PelvisRegistration PelvisTracker::register_views() {
  std::vector<geometry::PelvisView> bones;
  bones.reserve(views_.size());
  for (const Kept& k : views_) bones.push_back(k.bones);  // the images are shared, not copied
  geometry::PelvisRegistration r;
  if (bones.size() < 2) {
    r.refused = "one view of the pelvis so far (two are needed to fix its depth)";
    return r;
  }
  r = geometry::register_pelvis(scene_.pelvis, bones, options_.registration);
  // Refused: the views its last round could not use are forgotten (a frame without bones, a
  // menu on the monitor), to be offered again when the C-arm comes back to them. Found, all
  // stay: a view that dropped out of the last round was used before it. The registration
  // reports every view given, in order.
  if (!r.found && r.views.size() == views_.size()) {
    std::vector<Kept> kept;
    for (std::size_t i = 0; i < views_.size(); ++i)
      if (r.views[i].used) kept.push_back(std::move(views_[i]));
    views_ = std::move(kept);
  }
  return r;
}

bool PelvisTracker::moves_models(const geometry::PelvisRegistration& found) const {
  if (!found.found) return false;
  const double turn_at_100_mm = 100.0 * Eigen::AngleAxisd(found.rotation * moved_rotation_.transpose()).angle();
  return (found.shift_mm - moved_shift_mm_).norm() > options_.remake_mm || turn_at_100_mm > options_.remake_mm;
}

std::shared_ptr<const PelvisMovedModels> PelvisTracker::move_models(const geometry::PelvisRegistration& found) {
  auto moved = std::make_shared<const PelvisMovedModels>(scene_, found, deform_);
  moved_shift_mm_ = found.shift_mm;
  moved_rotation_ = found.rotation;
  return moved;
}

}  // namespace evar::node
