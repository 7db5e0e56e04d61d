// `evarnode sim patient`: a synthetic patient with its ground-truth distortion.
#include "commands.hpp"
#include "evar/node/logging.hpp"
#include "evar/sim/synthetic_patient.hpp"

namespace evar::app {

int run_sim_patient(const SyntheticSceneCommand& cmd) {
  const auto patient = sim::make_patient(sim::PatientPlan{cmd.seed, sim::parse_difficulty(cmd.difficulty),
                                                          sim::parse_truth_physics(cmd.physics), cmd.aorta_vertices,
                                                          cmd.iliac_vertices});
  const auto format = mesh_format_option(cmd.format);
  sim::write_patient(patient, cmd.out, format);
  const auto& p = patient.params;
  node::log().info("patient {} ({} difficulty, {} physics): aneurysm {:.0f} mm across, device ({:.2f} mm, bending length {:.0f} mm) through the {}",
             cmd.seed, cmd.difficulty, cmd.physics, 2.0 * p.aneurysm_max_radius_mm, p.device_thickness_mm,
             p.device_stiffness_length_mm, patient.truth.carrier);
  for (const auto& v : patient.truth.vessels)
    node::log().info("ground truth {:<11}: centerline moved up to {:.1f} mm, {} sections in contact", v.name,
               v.max_displacement_mm, v.contact_sections);
  node::log().info("wrote {} (scene.json, device.mrk.json, truth/, patient.json)", cmd.out.string());
  return 0;
}

}  // namespace evar::app
