#include "evar/sim/synthetic_patient.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

#include "evar/base/atomic_file.hpp"
#include "evar/sim/conforming_distortion.hpp"
#include "seeded_uniform.hpp"

namespace evar::sim {
ExampleSceneParams draw_patient_params(std::uint64_t seed, Difficulty difficulty) {
  SeededUniform draw(seed ^ 0x5eed'a0e7'11ac'0001ULL);
  const bool paper = difficulty == Difficulty::Paper;
  const auto coin = [&] { return draw.unit() >= 0.5; };  // the engine's top bit
  ExampleSceneParams p;
  p.seed = seed;
  p.variation = 0.0;  // the draws below are the variation
  // Fixed draw order: changing it changes every patient.
  p.aorta_top_z_mm = draw(140.0, 165.0);
  p.renal_z_mm = p.aorta_top_z_mm - draw(25.0, 40.0);
  const double neck = draw(15.0, 30.0);
  const double sac_top = p.renal_z_mm - neck;
  p.aneurysm_length_mm = std::min(draw(50.0, 85.0), sac_top - 12.0);  // ends >= 12 mm above the bifurcation
  p.aneurysm_centre_z_mm = sac_top - 0.5 * p.aneurysm_length_mm;
  p.aneurysm_max_radius_mm = draw(25.0, 37.5);
  p.aorta_radius_top_mm = draw(10.0, 13.0);
  p.aorta_radius_bifurcation_mm = std::min(draw(8.0, 10.5), p.aorta_radius_top_mm - 0.5);
  p.aorta_bow_anterior_mm = draw(2.0, 12.0);
  p.aorta_bow_left_mm = draw(-3.0, 8.0);
  p.iliac_start_lateral_mm = draw(3.0, 5.0);
  p.iliac_end_z_mm = draw(-165.0, -125.0);
  p.iliac_end_lateral_mm = draw(55.0, 80.0);
  p.iliac_end_anterior_mm = draw(5.0, 25.0);
  p.iliac_radius_proximal_mm = draw(4.5, 7.0);
  p.iliac_radius_distal_mm = std::min(draw(3.5, 5.0), p.iliac_radius_proximal_mm - 0.5);
  // At the paper's difficulty the iliacs are as tortuous as AAA patients' (a tortuosity
  // index, path over chord, of about 1.2-1.6 against 1.05-1.25).
  p.iliac_tortuosity_x_mm = paper ? draw(18.0, 38.0) : draw(4.0, 20.0);
  p.iliac_tortuosity_y_mm = paper ? draw(10.0, 24.0) : draw(3.0, 15.0);
  p.internal_iliac_arc_mm = draw(45.0, 65.0);
  p.device_in_left_iliac = coin();
  p.device_tip_z_mm = draw(p.renal_z_mm - 10.0, p.aorta_top_z_mm - 10.0);
  // Bending length grows with the fourth root of the wire's flexural rigidity: Super Stiff
  // to Lunderquist wires are 6-17 times a plain Amplatz wire, so 1.6-2 times its length.
  p.device_stiffness_length_mm = paper ? draw(60.0, 120.0) : draw(30.0, 60.0);
  p.device_thickness_mm = coin() ? 0.97 : 0.89;  // 0.038" or 0.035"
  return p;
}

SyntheticPatient make_patient(std::uint64_t seed, int aorta_vertices, int iliac_vertices) {
  return make_patient(PatientPlan{seed, Difficulty::Mild, TruthPhysics::Beam, aorta_vertices, iliac_vertices});
}

SyntheticPatient make_patient(const PatientPlan& plan) {
  const std::uint64_t seed = plan.seed;
  SyntheticPatient patient;
  patient.seed = seed;
  patient.difficulty = plan.difficulty;
  patient.physics = plan.physics;
  patient.params = draw_patient_params(seed, plan.difficulty);
  patient.params.aorta_vertices = plan.aorta_vertices;
  patient.params.iliac_vertices = plan.iliac_vertices;
  patient.preoperative = make_example_scene(patient.params);
  // The CT's bones: the pelvis the fluoroscopy shows (the phantom's bones do not depend on the seed).
  patient.preoperative.pelvis = pelvis_mesh(default_body_phantom());
  // On the table (at the paper's difficulty) the pelvis is shifted against the renal
  // level; the device is inserted into that anatomy, and the physics distorts it.
  patient.posture = draw_posture_change(seed, plan.difficulty, patient.params.renal_z_mm);
  ExampleScene on_table = patient.preoperative;
  apply(patient.posture, on_table);
  patient.preoperative.device = on_table.device;
  if (plan.physics == TruthPhysics::Conforming) {
    patient.conforming = draw_conforming_options(seed);
    patient.truth = distort_by_conforming(on_table, patient.conforming);
  } else {
    patient.truth = distort_by_device(on_table);
  }
  if (patient.truth.device_points_outside > 0)
    throw std::runtime_error("synthetic patient seed " + std::to_string(seed) + ": the ground-truth distortion leaves " +
                             std::to_string(patient.truth.device_points_outside) + " device points outside the vessels (worst " +
                             std::to_string(patient.truth.worst_outside_mm) + " mm, device point " +
                             std::to_string(patient.truth.worst_outside_point) + " from the tip, beside the " +
                             patient.truth.worst_outside_vessel + "); this anatomy is refused, use another seed");
  return patient;
}

void write_patient(const SyntheticPatient& patient, const std::filesystem::path& dir, geometry::MeshFormat format) {
  write_example_scene(patient.preoperative, dir, format);
  ExampleScene truth = patient.preoperative;
  for (std::size_t i = 0; i < truth.vessels.size(); ++i) {
    truth.vessels[i].mesh = patient.truth.vessels[i].mesh;
    truth.vessels[i].centerline = patient.truth.vessels[i].centerline;
  }
  truth.landmarks = patient.truth.landmarks;
  ExampleScene on_table = patient.preoperative;
  apply(patient.posture, on_table);
  truth.pelvis = on_table.pelvis;  // the pelvis on the table: the bones the fluoroscopy shows
  write_example_scene(truth, dir / "truth", format);

  const ExampleSceneParams& p = patient.params;
  nlohmann::ordered_json j;
  j["format"] = "evarnode-synthetic-patient";
  j["version"] = 1;
  j["seed"] = patient.seed;
  j["difficulty"] = to_string(patient.difficulty);
  j["coordinate_system"] = "LPS";
  j["units"] = "mm";
  j["anatomy"] = {{"aorta_top_z_mm", p.aorta_top_z_mm},
                  {"renal_z_mm", p.renal_z_mm},
                  {"aneurysm_centre_z_mm", p.aneurysm_centre_z_mm},
                  {"aneurysm_length_mm", p.aneurysm_length_mm},
                  {"aneurysm_max_radius_mm", p.aneurysm_max_radius_mm},
                  {"aorta_radius_top_mm", p.aorta_radius_top_mm},
                  {"aorta_radius_bifurcation_mm", p.aorta_radius_bifurcation_mm},
                  {"aorta_bow_anterior_mm", p.aorta_bow_anterior_mm},
                  {"aorta_bow_left_mm", p.aorta_bow_left_mm},
                  {"iliac_start_lateral_mm", p.iliac_start_lateral_mm},
                  {"iliac_end_z_mm", p.iliac_end_z_mm},
                  {"iliac_end_lateral_mm", p.iliac_end_lateral_mm},
                  {"iliac_end_anterior_mm", p.iliac_end_anterior_mm},
                  {"iliac_radius_proximal_mm", p.iliac_radius_proximal_mm},
                  {"iliac_radius_distal_mm", p.iliac_radius_distal_mm},
                  {"iliac_tortuosity_x_mm", p.iliac_tortuosity_x_mm},
                  {"iliac_tortuosity_y_mm", p.iliac_tortuosity_y_mm},
                  {"internal_iliac_arc_mm", p.internal_iliac_arc_mm}};
  j["device"] = {{"iliac", p.device_in_left_iliac ? "iliac_left" : "iliac_right"},
                 {"tip_z_mm", p.device_tip_z_mm},
                 {"bending_length_mm", p.device_stiffness_length_mm},
                 {"thickness_mm", p.device_thickness_mm},
                 {"file", "device.mrk.json"}};
  nlohmann::ordered_json vessels = nlohmann::ordered_json::array();
  for (const auto& v : patient.truth.vessels)
    vessels.push_back({{"name", v.name},
                       {"max_centerline_displacement_mm", v.max_displacement_mm},
                       {"contact_sections", v.contact_sections}});
  nlohmann::ordered_json mechanics = nlohmann::ordered_json::object();
  if (patient.physics == TruthPhysics::Conforming)
    mechanics = {{"wire_offset_fraction", patient.conforming.wire_offset_fraction},
                 {"fold_fraction", patient.conforming.fold_fraction},
                 {"aorta_decay_mm", patient.conforming.aorta_decay_mm}};
  const Eigen::Vector3d& shift = patient.posture.pelvis_shift_mm;
  j["posture_change"] = {{"pelvis_shift_mm", {shift.x(), shift.y(), shift.z()}},
                         {"from_z_mm", patient.posture.renal_z_mm},
                         {"full_below_z_mm", patient.posture.pelvis_z_mm}};
  j["ground_truth"] = {{"directory", "truth"},
                       {"physics", to_string(patient.physics)},
                       {"model", patient.physics == TruthPhysics::Conforming
                                     ? "carrier iliac threaded on the wire (folds and slides), aorta held at the renal level as a string under tension, sections turned"
                                     : "centerline beams on elastic foundation, device contact, rigid re-sweep of sections"},
                       {"parameters", mechanics},
                       {"carrier", patient.truth.carrier},
                       {"contact_rounds", patient.truth.rounds}, {"mesh_passes", patient.truth.mesh_passes},
                       {"max_intrusion_mm", patient.truth.max_intrusion_mm},
                       {"vessels", vessels}};
  base::write_file_atomically(dir / "patient.json", j.dump(2) + "\n");
}

}  // namespace evar::sim
