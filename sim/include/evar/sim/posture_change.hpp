#pragma once
// The anatomy on the table is not the anatomy of the preoperative CT: between the CT and
// the intervention the patient lies differently (legs, lordosis), and between the
// registration to the renal arteries and a fluoroscopy run the renal level rides on the
// diaphragm while the pelvis stays. Registered to the renals, the models then meet a
// pelvis shifted against them. A posture change is that shift: nothing at and above the
// renal level, the whole shift from the aortic bifurcation down, a smooth ramp between.
#include <Eigen/Core>
#include <cstdint>

#include "evar/sim/body_phantom.hpp"
#include "evar/sim/example_scene.hpp"
#include "evar/sim/patient_plan.hpp"

namespace evar::sim {

struct PostureChange {
  Eigen::Vector3d pelvis_shift_mm = Eigen::Vector3d::Zero();  ///< LPS, of everything below the bifurcation
  double renal_z_mm = 0.0;   ///< no shift at and above this height
  double pelvis_z_mm = 0.0;  ///< the full shift at and below this height (the bifurcation)

  /// The shift at a point: pelvis_shift_mm times a smoothstep from renal_z_mm down to pelvis_z_mm.
  Eigen::Vector3d shift_at(const Eigen::Vector3d& x) const;
  bool is_none() const { return pelvis_shift_mm.isZero(); }
};

/// None at Difficulty::Mild; at Difficulty::Paper (its own stream from the seed) a
/// cranio-caudal shift uniform in ±12 mm (the renal level's respiratory excursion is
/// 10-20 mm) and lateral and antero-posterior shifts in ±3 mm.
PostureChange draw_posture_change(std::uint64_t seed, Difficulty difficulty, double renal_z_mm);

/// Moves every mesh vertex, centerline point, landmark and device point of `scene` by the
/// change (radii unchanged).
void apply(const PostureChange& change, ExampleScene& scene);

/// Moves every part of the body phantom (bones, gas) by the change at its centre, so the
/// skeleton in the fluoroscopy lies where the vessels at its height went: the pelvis and
/// the sacrum by the whole shift, the lumbar vertebrae along the ramp. A bony landmark
/// then shows the pelvis's place as the vessels it holds have it.
void apply(const PostureChange& change, BodyPhantom& body);

}  // namespace evar::sim
