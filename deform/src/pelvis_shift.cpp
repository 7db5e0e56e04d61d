#include "evar/deform/pelvis_shift.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <string>

#include "evar/base/input_error.hpp"
#include "evar/base/quantity_text.hpp"
#include "evar/geometry/polyline.hpp"

namespace evar::deform {

Eigen::Vector3d PelvisShift::displacement_at(const Eigen::Vector3d& x_mm) const {
  const Eigen::Vector3d axis = bifurcation_point_mm - renal_point_mm;
  if (!(axis.squaredNorm() > 0.0)) return Eigen::Vector3d::Zero();  // no ramp (pelvis_shift_for makes one of 10 mm or more)
  const double f = std::clamp((x_mm - renal_point_mm).dot(axis) / axis.squaredNorm(), 0.0, 1.0);
  return f * f * (3.0 - 2.0 * f) * (rotation * (x_mm - pivot_mm) + pivot_mm + shift_mm - x_mm);
}

PelvisShift pelvis_shift_for(const geometry::Scene& scene, const Eigen::Vector3d& shift_mm, const Eigen::Matrix3d& rotation,
                             const Eigen::Vector3d& pivot_mm) {
  if (!shift_mm.allFinite() || !pivot_mm.allFinite()) throw base::InputError("pelvis shift: not a finite displacement");
  if (!rotation.allFinite() || (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).norm() > 1e-6 || rotation.determinant() < 0.0)
    throw base::InputError("pelvis shift: the pelvis's turn is not a rotation");
  const auto aorta = std::find_if(scene.vessels.begin(), scene.vessels.end(),
                                  [](const geometry::Vessel& v) { return v.kind == geometry::VesselKind::Aorta; });
  if (aorta == scene.vessels.end() || aorta->centerline.size() < 2)
    throw base::InputError(scene.file.string() + ": a pelvis shift needs the aorta's centerline (renal level to bifurcation)");
  PelvisShift out;
  out.shift_mm = shift_mm;
  out.rotation = rotation;
  out.pivot_mm = pivot_mm;
  Eigen::Vector3d renal_sum = Eigen::Vector3d::Zero();
  int renal_count = 0;
  for (const auto& lm : scene.landmarks)
    if (lm.label.rfind("renal", 0) == 0) renal_sum += lm.position_lps, ++renal_count;
  out.renal_point_mm = renal_count > 0 ? geometry::project_onto(aorta->centerline, renal_sum / renal_count).point : aorta->centerline.front();
  out.bifurcation_point_mm = aorta->centerline.back();
  const double span_mm = (out.bifurcation_point_mm - out.renal_point_mm).norm();
  if (span_mm < 10.0)
    throw base::InputError(scene.file.string() + ": the renal level and the aortic bifurcation are " +
                           base::quantity_text(span_mm, "mm") +
                           " apart along the aorta's centerline; a pelvis shift needs at least 10 mm to ramp over "
                           "(check the renal landmarks and that the centerline ends at the bifurcation)");
  return out;
}

void apply(const PelvisShift& shift, geometry::Scene& scene) {
  for (auto& v : scene.vessels) {
    auto& V = v.mesh.mesh.V;
    for (Eigen::Index i = 0; i < V.rows(); ++i) {
      const Eigen::Vector3d x = V.row(i).transpose();
      V.row(i) = (x + shift.displacement_at(x)).transpose();
    }
    for (auto& c : v.centerline) c += shift.displacement_at(c);
    v.proxy_path.clear();
  }
  for (auto& lm : scene.landmarks) lm.position_lps += shift.displacement_at(lm.position_lps);
}

}  // namespace evar::deform
