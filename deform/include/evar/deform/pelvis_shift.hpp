#pragma once
// Where the pelvis lies against models registered to the renal arteries. The paper aligns
// the preoperative models on the renal arteries; between the CT and the fluoroscopy the
// pelvis moves against that level (the patient lies differently, the renal level rides on
// the diaphragm), and the iliacs, held in the pelvis by their branches, the inguinal
// ligament and the femoral access, move with it. The device does not show that motion: a
// stiff wire runs along it. Bony landmarks do (a 2D/3D registration of the pelvis, as
// fusion-imaging systems make one). Given the pelvis's displacement, the models are moved
// before they are bent: nothing at and above the renal level, the whole displacement at
// and below the aortic bifurcation, a smooth ramp along the aorta between (C1 at both
// ends: the registered level and the rigid pelvis both hold their neighbourhood still).
#include <Eigen/Core>

#include "evar/geometry/scene.hpp"

namespace evar::deform {

struct PelvisShift {
  /// The pelvis's pose against the registered models, scene LPS: a pelvic point x lies at
  /// rotation·(x − pivot_mm) + pivot_mm + shift_mm (geometry::PelvisRegistration's pose).
  Eigen::Vector3d shift_mm = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d pivot_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d renal_point_mm = Eigen::Vector3d::Zero();        ///< where the ramp starts (no displacement)
  Eigen::Vector3d bifurcation_point_mm = Eigen::Vector3d::Zero();  ///< where it ends (the whole displacement)

  /// The displacement at a point: the pelvis's motion there times smoothstep of the point's
  /// place along renal_point_mm → bifurcation_point_mm (0 before it, 1 past it).
  Eigen::Vector3d displacement_at(const Eigen::Vector3d& x_mm) const;
};

/// The ramp for `scene`: from the renal level (the point of the aortic centerline nearest
/// the mean of the landmarks labelled "renal…", or the centerline's proximal end when there
/// are none) to the aortic bifurcation (the centerline's distal end). Throws InputError
/// when the two are under 10 mm apart along the aorta (a ramp that short would shear it),
/// for a displacement that is not finite and for a rotation that is not one.
PelvisShift pelvis_shift_for(const geometry::Scene& scene, const Eigen::Vector3d& shift_mm,
                             const Eigen::Matrix3d& rotation = Eigen::Matrix3d::Identity(),
                             const Eigen::Vector3d& pivot_mm = Eigen::Vector3d::Zero());

/// Moves every vessel's vertices and centerline and every landmark of `scene` by the
/// displacement. The scene's proxy files are dropped from it (they were made for the
/// unmoved meshes; deform makes the proxies anew).
void apply(const PelvisShift& shift, geometry::Scene& scene);

}  // namespace evar::deform
