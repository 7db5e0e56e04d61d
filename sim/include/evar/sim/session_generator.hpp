#pragma once
// A whole simulated intervention as a recorded session (`evarnode sim session`): a
// synthetic patient, the C-arm moving between angulations (moving flag set while it
// moves), fluoroscopy runs of the inserted device in two or more views, and DSA-like
// contrast frames of the iliac bifurcation, with the ground truth.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "evar/session/session.hpp"
#include "evar/sim/patient_plan.hpp"
#include "evar/sim/registration_residual.hpp"
#include "evar/sim/xray_render.hpp"

namespace evar::sim {

struct SessionPlan {
  std::uint64_t seed = 1;           ///< patient and noise
  Difficulty difficulty = Difficulty::Mild;  ///< anatomy, wire and registration residual
  TruthPhysics physics = TruthPhysics::Beam; ///< the ground-truth mechanics
  int detector_px = 1024;           ///< square detector
  double pixel_spacing_mm = 0.3;    ///< at the detector (a 30 cm panel at 1024)
  double sid_mm = 1200.0, sod_mm = 800.0;
  double fluoro_fps = 15.0;         ///< pulsed fluoroscopy rate
  double fluoro_seconds = 4.0;      ///< per view
  double dsa_fps = 4.0;
  double dsa_seconds = 3.0;         ///< mask (first 0.5 s), then the bolus
  double rotation_deg_per_s = 20.0; ///< C-arm speed between views
  double carm_rate_hz = 10.0;       ///< geometry samples, moving or still (and at every change)
  int aorta_vertices = 7500, iliac_vertices = 3500;
  XRayOptions xray;
  /// Set: the frames are the C-arm monitor's picture through this mapping (monitor_picture,
  /// with the patient, the angulation and a frame counter burned into its text regions),
  /// and session.json carries it. The true ostia stay in detector pixels.
  std::optional<geometry::VideoMapping> video_out;
  /// Set: the C-arm has two zoom modes, listed in session.json, with the mode of each C-arm
  /// sample in carm.csv: 1, the whole detector, and 2, its central two thirds in as many
  /// pixels; the last fluoroscopy run switches from 1 to 2 halfway, and the DSA run is in 2.
  bool zoom_change = false;
};

struct GeneratedSession {
  session::Session session;
  std::string carrier;      ///< the iliac holding the device
  RegistrationResidual residual;  ///< what the registration given to the node is off by
  double render_seconds = 0.0;
};

/// Renders and writes the session into `directory` (created): session.json, frames,
/// carm.csv, registration.json, patient/ (the synthetic patient: preoperative scene,
/// device, truth/) and truth/ostia_2d.csv. Frames and true ostia are rendered through the
/// true registration; registration.json holds it moved by the plan's registration residual
/// (truth/registration.json the true one, when they differ). The views: AP, LAO 35°, and the bifurcation
/// view of the carrier iliac (25° contralateral oblique, 15° caudal), each settled before
/// its fluoroscopy run; the DSA run is in the last view. `progress(done, total)` is
/// called after each frame. Throws what make_patient throws (a refused seed) and
/// std::runtime_error on write errors.
GeneratedSession generate_session(const SessionPlan& plan, const std::filesystem::path& directory,
                                  const std::function<void(std::size_t, std::size_t)>& progress = {});

}  // namespace evar::sim
