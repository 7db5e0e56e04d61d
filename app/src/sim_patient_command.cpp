// `evarnode sim patient`: a synthetic patient with its ground-truth distortion.
#include "commands.hpp"
#include "evar/sim/synthetic_patient.hpp"
#include "logging.hpp"

namespace evar::app {

int run_sim_patient(const SyntheticSceneCommand& cmd) {
  const auto patient = sim::make_patient(cmd.seed, cmd.aorta_vertices, cmd.iliac_vertices);
  const auto format = mesh_format_option(cmd.format);
  sim::write_patient(patient, cmd.out, format);
  const auto& p = patient.params;
  log().info("patient {}: aneurysm {:.0f} mm across, device ({:.2f} mm) through the {}", cmd.seed,
             2.0 * p.aneurysm_max_radius_mm, p.device_thickness_mm, patient.truth.carrier);
  for (const auto& v : patient.truth.vessels)
    log().info("ground truth {:<11}: centerline moved up to {:.1f} mm, {} sections in contact", v.name,
               v.max_displacement_mm, v.contact_sections);
  log().info("wrote {} (scene.json, device.mrk.json, truth/, patient.json)", cmd.out.string());
  return 0;
}

}  // namespace evar::app
