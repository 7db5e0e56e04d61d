#pragma once
// Synthetic aorto-iliac patients for development and evaluation: anatomy drawn from adult
// ranges by a seed, a stiff device through one iliac, and the ground-truth distortion the
// device causes (device_distortion.hpp, a model other than the product's ARAP).
#include <cstdint>
#include <filesystem>
#include <string>

#include "evar/geometry/mesh_io.hpp"
#include "evar/sim/conforming_distortion.hpp"
#include "evar/sim/device_distortion.hpp"
#include "evar/sim/example_scene.hpp"
#include "evar/sim/patient_plan.hpp"
#include "evar/sim/posture_change.hpp"

namespace evar::sim {

/// Anatomy and device drawn uniformly from adult ranges (documented in
/// docs/SYNTHETIC_PATIENTS.md): suprarenal aortic radius 10–13 mm, infrarenal aneurysm
/// 50–75 mm across with a 15–30 mm neck below the renal ostia, common+external iliacs of
/// 9–14 mm proximal diameter with 4–20 mm lateral and 3–15 mm antero-posterior tortuosity,
/// the internal iliac ostium 45–65 mm down the iliac; a 0.035" or 0.038" stiff wire
/// (bending length 30–60 mm) through the left or right iliac, tip 10 mm below the renal
/// ostia to 10 mm below the aortic top. Deterministic: the same seed gives the same
/// parameters on any platform. Mesh resolution is left at the defaults. At
/// Difficulty::Paper the same draws map to more tortuous iliacs (lateral 18–38 mm,
/// antero-posterior 10–24 mm) and stiffer wires (bending length 60–120 mm).
ExampleSceneParams draw_patient_params(std::uint64_t seed, Difficulty difficulty = Difficulty::Mild);

struct SyntheticPatient {
  std::uint64_t seed = 0;
  Difficulty difficulty = Difficulty::Mild;
  TruthPhysics physics = TruthPhysics::Beam;
  ExampleSceneParams params;
  ConformingOptions conforming;  ///< the drawn mechanics when physics is Conforming
  PostureChange posture;         ///< the pelvis on the table against the CT (none at Mild)
  ExampleScene preoperative;  ///< what CT shows: undistorted vessels and landmarks; the device as inserted
  DeviceDistortion truth;     ///< the vessels as the device really bends them
};

/// draw_patient_params(plan.seed, plan.difficulty) with the plan's vertex counts, the
/// scene, the posture change on the table (draw_posture_change) and the ground truth by the
/// plan's physics (distort_by_device, or distort_by_conforming with
/// draw_conforming_options(seed)) of the anatomy on the table, where the device lies. Throws like
/// make_example_scene and the physics, and
/// std::runtime_error naming the seed when the ground truth does not hold the device
/// (distortion.device_points_outside > 0; a few percent of seeds, see
/// docs/SYNTHETIC_PATIENTS.md): such a seed is refused, never written.
SyntheticPatient make_patient(const PatientPlan& plan);
/// make_patient at Difficulty::Mild with the beam physics.
SyntheticPatient make_patient(std::uint64_t seed, int aorta_vertices = 7500, int iliac_vertices = 3500);

/// Writes the preoperative scene as write_example_scene does (dir/scene.json, meshes,
/// centerlines, landmarks.mrk.json, device.mrk.json), the ground truth under dir/truth/
/// (the distorted meshes under the same file names, <vessel>.centerline.mrk.json,
/// landmarks.mrk.json, device.mrk.json) and dir/patient.json (seed, parameters, carrier
/// iliac, distortion summary). Returns nothing; throws std::runtime_error on write errors.
void write_patient(const SyntheticPatient& patient, const std::filesystem::path& dir,
                   geometry::MeshFormat format = geometry::MeshFormat::StlBinary);

}  // namespace evar::sim
