// `evarnode sim session`: a whole simulated intervention as a recorded session.
#include "commands.hpp"
#include "evar/sim/session_generator.hpp"
#include "logging.hpp"
#include "progress_bar.hpp"

namespace evar::app {

int run_sim_session(const SimSessionCommand& cmd) {
  sim::SessionPlan plan;
  plan.seed = cmd.seed;
  plan.detector_px = cmd.detector_px;
  plan.pixel_spacing_mm = 0.3 * 1024.0 / cmd.detector_px;  // the same 30 cm panel at any resolution
  plan.fluoro_seconds = cmd.fluoro_seconds;
  plan.fluoro_fps = cmd.fluoro_fps;
  ProgressBar bar("frames", cmd.progress);
  const auto generated = sim::generate_session(plan, cmd.out, [&](std::size_t done, std::size_t total) { bar.update(done, total); });
  bar.finish();
  const auto& s = generated.session;
  log().info("session seed {}: {} frames ({}x{} px), {} C-arm samples, device in the {}, {} true ostium positions; {:.1f} s",
             cmd.seed, s.frames.size(), s.detector.cols, s.detector.rows, s.carm.size(), generated.carrier,
             s.truth ? s.truth->ostia.size() : 0, generated.render_seconds);
  log().info("wrote {} (play it with: evarnode replay {})", cmd.out.string(), cmd.out.string());
  return 0;
}

}  // namespace evar::app
