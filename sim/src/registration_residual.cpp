#include "evar/sim/registration_residual.hpp"

#include <Eigen/Geometry>
#include <numbers>

#include "seeded_uniform.hpp"

namespace evar::sim {

Eigen::Matrix4d RegistrationResidual::transform() const {
  constexpr double kRad = std::numbers::pi / 180.0;
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(rotation_deg.z() * kRad, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(rotation_deg.y() * kRad, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(rotation_deg.x() * kRad, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
  M.topLeftCorner<3, 3>() = R;
  M.topRightCorner<3, 1>() = centre_lps + translation_mm + R * (alignment_mm - centre_lps);
  return M;
}

RegistrationResidual draw_registration_residual(std::uint64_t seed, Difficulty difficulty, const Eigen::Vector3d& centre_lps) {
  RegistrationResidual r;
  r.centre_lps = centre_lps;
  if (difficulty == Difficulty::Mild) return r;
  SeededUniform draw(seed ^ 0x4e61'5265'6733'0001ULL);
  for (int k = 0; k < 3; ++k) r.rotation_deg(k) = draw(-5.0, 5.0);
  for (int k = 0; k < 3; ++k) r.translation_mm(k) = draw(-1.0, 1.0);
  return r;
}

}  // namespace evar::sim
