// `evarnode sim session`: a whole simulated intervention as a recorded session.
#include "commands.hpp"
#include "evar/base/input_error.hpp"
#include "evar/geometry/video_mapping.hpp"
#include "evar/node/logging.hpp"
#include "evar/sim/session_generator.hpp"
#include "progress_bar.hpp"

namespace evar::app {

int run_sim_session(const SimSessionCommand& cmd) {
  sim::SessionPlan plan;
  plan.seed = cmd.seed;
  plan.detector_px = cmd.detector_px;
  plan.pixel_spacing_mm = 0.3 * 1024.0 / cmd.detector_px;  // the same 30 cm panel at any resolution
  plan.fluoro_seconds = cmd.fluoro_seconds;
  plan.fluoro_fps = cmd.fluoro_fps;
  plan.difficulty = sim::parse_difficulty(cmd.difficulty);
  plan.physics = sim::parse_truth_physics(cmd.physics);
  plan.zoom_change = cmd.zoom_change;
  if (!cmd.video_out.empty()) {
    plan.video_out = geometry::read_video_mapping(cmd.video_out);
    if (const auto problem = geometry::video_mapping_fit_problem(*plan.video_out, plan.detector_px, plan.detector_px);
        !problem.empty())
      throw base::InputError(cmd.video_out.string() + ": " + problem + " (the detector is " +
                             std::to_string(plan.detector_px) + " x " + std::to_string(plan.detector_px) + ")");
  }
  ProgressBar bar("frames", cmd.progress);
  const auto generated = sim::generate_session(plan, cmd.out, [&](std::size_t done, std::size_t total) { bar.update(done, total); });
  bar.finish();
  const auto& s = generated.session;
  if (s.video_mapping)
    node::log().info("frames are the monitor's picture: {} x {}, the detector image in [{}, {}, {}, {}]", s.video_mapping->video_cols,
                     s.video_mapping->video_rows, s.video_mapping->image_rect.x, s.video_mapping->image_rect.y,
                     s.video_mapping->image_rect.width, s.video_mapping->image_rect.height);
  for (const auto& z : s.zoom_modes)
    node::log().info("zoom mode {} \"{}\": {} x {} pixels of {:.3f} mm", z.number, z.name, z.cols, z.rows, z.col_spacing_mm);
  node::log().info("session seed {}: {} frames (detector {}x{} px), {} C-arm samples, device in the {}, {} true ostium positions; {:.1f} s",
             cmd.seed, s.frames.size(), s.detector.cols, s.detector.rows, s.carm.size(), generated.carrier,
             s.truth ? s.truth->ostia.size() : 0, generated.render_seconds);
  if (!generated.residual.is_identity()) {
    const auto& r = generated.residual;
    node::log().info("registration residual about the renal level: rotation {:.1f}, {:.1f}, {:.1f} deg (x, y, z), shift {:.1f}, {:.1f}, {:.1f} mm",
               r.rotation_deg.x(), r.rotation_deg.y(), r.rotation_deg.z(), r.translation_mm.x(), r.translation_mm.y(),
               r.translation_mm.z());
  }
  node::log().info("wrote {} (play it with: evarnode replay {})", cmd.out.string(), cmd.out.string());
  return 0;
}

}  // namespace evar::app
