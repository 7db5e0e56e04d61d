#pragma once
// The registration residual of a simulated session. In the paper's workflow the
// preoperative CT is registered to the C-arm before the intervention and the models are
// aligned on the renal arteries; what remains (the registration's own error and the
// patient's motion between registration and fluoroscopy) is a small rigid motion about the
// renal level. The node receives the preoperative scene through a registration that is off
// by it: the scene it draws is the true anatomy moved by `transform()`.
#include <Eigen/Core>
#include <cstdint>

#include "evar/sim/patient_plan.hpp"

namespace evar::sim {

struct RegistrationResidual {
  Eigen::Vector3d rotation_deg = Eigen::Vector3d::Zero();    ///< about the LPS x, y, z axes, applied x, then y, then z
  Eigen::Vector3d translation_mm = Eigen::Vector3d::Zero();  ///< of the centre
  Eigen::Vector3d centre_lps = Eigen::Vector3d::Zero();      ///< the renal level (mm, CT LPS)
  /// The registration to the renal arteries: the shift that puts the preoperative renal
  /// ostia's midpoint on the true one, applied before the residual.
  Eigen::Vector3d alignment_mm = Eigen::Vector3d::Zero();

  /// The rigid map M (4x4, CT LPS mm) taking the true anatomy to where the node's
  /// registration puts it: M x = R (x + alignment - centre) + centre + translation.
  Eigen::Matrix4d transform() const;
  bool is_identity() const { return rotation_deg.isZero() && translation_mm.isZero() && alignment_mm.isZero(); }
};

/// Drawn per session from the seed (its own stream, so the patient does not change):
/// none at Difficulty::Mild; at Difficulty::Paper each rotation uniform in ±5° and each
/// translation in ±1 mm (docs/SYNTHETIC_PATIENTS.md says where these figures come from),
/// about `centre_lps`.
RegistrationResidual draw_registration_residual(std::uint64_t seed, Difficulty difficulty, const Eigen::Vector3d& centre_lps);

}  // namespace evar::sim
