#include "evar/sim/posture_change.hpp"

#include <algorithm>

#include "seeded_uniform.hpp"

namespace evar::sim {

Eigen::Vector3d PostureChange::shift_at(const Eigen::Vector3d& x) const {
  const double span = renal_z_mm - pelvis_z_mm;
  const double f = span > 0.0 ? std::clamp((renal_z_mm - x.z()) / span, 0.0, 1.0) : 1.0;
  return f * f * (3.0 - 2.0 * f) * pelvis_shift_mm;
}

PostureChange draw_posture_change(std::uint64_t seed, Difficulty difficulty, double renal_z_mm) {
  PostureChange c;
  c.renal_z_mm = renal_z_mm;
  if (difficulty == Difficulty::Mild) return c;
  SeededUniform draw(seed ^ 0x9057'0e50'1f70'0001ULL);
  c.pelvis_shift_mm = {draw(-3.0, 3.0), draw(-3.0, 3.0), draw(-12.0, 12.0)};
  return c;
}

void apply(const PostureChange& change, ExampleScene& scene) {
  if (change.is_none()) return;
  const auto move = [&](Eigen::Vector3d& x) { x += change.shift_at(x); };
  for (auto& v : scene.vessels) {
    for (Eigen::Index i = 0; i < v.mesh.V.rows(); ++i) {
      Eigen::Vector3d x = v.mesh.V.row(i).transpose();
      move(x);
      v.mesh.V.row(i) = x.transpose();
    }
    for (auto& c : v.centerline) move(c);
  }
  for (auto& lm : scene.landmarks) move(lm.position_lps);
  for (auto& d : scene.device) move(d);
  for (Eigen::Index i = 0; i < scene.pelvis.V.rows(); ++i) {
    Eigen::Vector3d x = scene.pelvis.V.row(i).transpose();
    move(x);
    scene.pelvis.V.row(i) = x.transpose();
  }
}

void apply(const PostureChange& change, BodyPhantom& body) {
  if (change.is_none()) return;
  for (auto& part : body.parts) part.centre_mm += change.shift_at(part.centre_mm);
}

}  // namespace evar::sim
