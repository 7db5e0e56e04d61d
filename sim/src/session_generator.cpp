#include "evar/sim/session_generator.hpp"

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <stdexcept>

#include "evar/sim/body_phantom.hpp"
#include "evar/sim/monitor_picture.hpp"
#include "evar/sim/synthetic_patient.hpp"
#include "seeded_uniform.hpp"

namespace evar::sim {
namespace {

// As the C-arm's monitor writes it: "LAO 35  CAU 15".
std::string angulation_text(double primary_deg, double secondary_deg) {
  char b[64];
  std::snprintf(b, sizeof b, "%s %.0f  %s %.0f", primary_deg >= 0 ? "LAO" : "RAO", std::abs(primary_deg),
                secondary_deg >= 0 ? "CRA" : "CAU", std::abs(secondary_deg));
  return b;
}

constexpr std::int64_t kSecond = 1'000'000'000;

struct ViewPose {
  double primary_deg, secondary_deg;
  Eigen::Vector3d table_mm;
};

}  // namespace

GeneratedSession generate_session(const SessionPlan& plan, const std::filesystem::path& dir,
                                  const std::function<void(std::size_t, std::size_t)>& progress) {
  if (plan.detector_px < 16 || !(plan.pixel_spacing_mm > 0.0) || !(plan.fluoro_fps > 0.0) || !(plan.dsa_fps > 0.0) ||
      !(plan.fluoro_seconds > 0.0) || !(plan.dsa_seconds > 0.5) || !(plan.rotation_deg_per_s > 0.0) || !(plan.carm_rate_hz > 0.0) || !(plan.carm_rate_hz <= 1000.0) ||
      !(plan.sod_mm > 0.0 && plan.sod_mm < plan.sid_mm))
    throw std::invalid_argument("generate_session: implausible plan (sizes, rates and durations must be positive, SOD < SID)");
  const auto start = std::chrono::steady_clock::now();
  const SyntheticPatient patient =
      make_patient(PatientPlan{plan.seed, plan.difficulty, plan.physics, plan.aorta_vertices, plan.iliac_vertices});
  write_patient(patient, dir / "patient");

  GeneratedSession out;
  out.carrier = patient.truth.carrier;
  session::Session& s = out.session;
  s.directory = dir;
  s.scene = "patient/scene.json";
  s.device_thickness_mm = patient.preoperative.device_thickness_mm;
  s.detector = {plan.detector_px, plan.detector_px, plan.pixel_spacing_mm, plan.pixel_spacing_mm};
  s.video_mapping = plan.video_out;
  int zoom_now = 0;  // the mode the C-arm is in (0: it has none)
  if (plan.zoom_change) {
    const double whole_cm = plan.detector_px * plan.pixel_spacing_mm / 10.0;
    char names[2][32];
    std::snprintf(names[0], sizeof names[0], "%.0f cm", whole_cm);
    std::snprintf(names[1], sizeof names[1], "%.0f cm", whole_cm * 2.0 / 3.0);
    const int n = plan.detector_px;
    s.zoom_modes = {geometry::centred_zoom_mode(1, names[0], n, n, plan.pixel_spacing_mm),
                    geometry::centred_zoom_mode(2, names[1], n, n, plan.pixel_spacing_mm * 2.0 / 3.0)};
    zoom_now = 1;
  }
  // Registration: CT point (0, 0, 50) (the aneurysm, renal ostia in the field) at the
  // isocenter, turned by a degree or two as a real registration would be.
  SeededUniform uniform(plan.seed ^ 0xC0A4'5E55'1011ULL);
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(uniform(-2.0, 2.0) * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(uniform(-2.0, 2.0) * std::numbers::pi / 180.0, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  const Eigen::Vector3d centre_ct(0.0, 0.0, 50.0);
  s.ct_to_carm.setIdentity();
  s.ct_to_carm.topLeftCorner<3, 3>() = R;
  s.ct_to_carm.topRightCorner<3, 1>() = -R * centre_ct;
  // At the paper's difficulty the models are registered to the renal arteries as the
  // paper's are: moved so that the preoperative renal ostia's midpoint lies on the true
  // (distorted) one, then off by the residual, which turns about that point.
  const auto renal_midpoint = [](const std::vector<geometry::ControlPoint>& landmarks) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    int n = 0;
    for (const auto& lm : landmarks)
      if (lm.label.rfind("renal", 0) == 0) sum += lm.position_lps, ++n;
    return n > 0 ? Eigen::Vector3d(sum / n) : Eigen::Vector3d::Zero();
  };
  const Eigen::Vector3d renal_true = renal_midpoint(patient.truth.landmarks);
  out.residual = draw_registration_residual(plan.seed, plan.difficulty, renal_true);
  if (plan.difficulty == Difficulty::Paper) out.residual.alignment_mm = renal_true - renal_midpoint(patient.preoperative.landmarks);

  // The views: AP, LAO 35, and the carrier's bifurcation (contralateral oblique, caudal),
  // with the table moved so the bifurcation is at the isocenter.
  const bool right = patient.truth.carrier == "iliac_right";
  const Eigen::Vector3d bifurcation_ct(right ? -25.0 : 25.0, 0.0, -25.0);
  const std::vector<ViewPose> poses{{0.0, 0.0, Eigen::Vector3d::Zero()},
                                    {35.0, 0.0, Eigen::Vector3d::Zero()},
                                    {right ? 25.0 : -25.0, -15.0, -R * (bifurcation_ct - centre_ct)}};

  // The skeleton lies as the anatomy on the table does: shifted with the pelvis.
  BodyPhantom body = default_body_phantom(static_cast<unsigned>(plan.seed));
  apply(patient.posture, body);
  std::vector<const geometry::TriangleMesh*> vessels;
  for (const auto& v : patient.truth.vessels) vessels.push_back(&v.mesh);

  // Timeline.
  struct FramePlan {
    std::int64_t t;
    std::size_t carm;  // index of the sample in force
    std::string source;
    double contrast;
  };
  std::vector<FramePlan> frames;
  std::int64_t t = kSecond;
  const auto sample = [&](const ViewPose& p, bool fluoro, bool moving) {
    session::CArmSample c;
    c.timestamp_ns = t;
    c.primary_deg = p.primary_deg;
    c.secondary_deg = p.secondary_deg;
    c.sid_mm = plan.sid_mm;
    c.sod_mm = plan.sod_mm;
    c.table_mm = {p.table_mm.x(), p.table_mm.y(), p.table_mm.z()};
    c.fluoro_on = fluoro;
    c.moving = moving;
    c.zoom_mode = zoom_now;
    s.carm.push_back(c);
  };
  // A C-arm interface streams its state at a steady rate, not only when something changes:
  // between the changes the state in force is sent again every 1/carm_rate_hz, so a
  // receiver can tell a silent link from a still C-arm.
  const auto period = static_cast<std::int64_t>(std::llround(1e9 / plan.carm_rate_hz));
  const auto hold = [&](const ViewPose& p, bool fluoro, std::int64_t until) {
    const std::int64_t end = until;
    for (std::int64_t next = t + period; next < end; next += period) {
      t = next;
      sample(p, fluoro, false);
    }
    t = end;
  };
  // `zoom_to` (not 0): the C-arm switches to that zoom mode halfway through the run.
  const auto run = [&](const ViewPose& p, const std::string& source, double fps, double seconds, int zoom_to = 0) {
    sample(p, true, false);
    std::size_t in_force = s.carm.size() - 1;  // the rendering's key: one pose (and mode) per part of a run
    const auto n = static_cast<int>(std::lround(fps * seconds));
    const std::int64_t t0 = t;
    for (int k = 0; k < n; ++k) {
      const std::int64_t tk = t0 + static_cast<std::int64_t>(std::llround(k * 1e9 / fps));
      if (zoom_to != 0 && k == n / 2) {
        // Switched between two pulses: the new mode's first sample comes before its first frame.
        hold(p, true, tk - static_cast<std::int64_t>(std::llround(0.5e9 / fps)));
        zoom_now = zoom_to;
        sample(p, true, false);
        in_force = s.carm.size() - 1;
      }
      const double since = k / fps;
      const double contrast = source == "dsa" ? std::clamp((since - 0.5) / 0.5, 0.0, 1.0) : 0.0;
      frames.push_back({tk, in_force, source, contrast});
    }
    hold(p, true, t0 + static_cast<std::int64_t>(std::llround(n * 1e9 / fps)));
    sample(p, false, false);  // beam off
  };
  const auto move = [&](const ViewPose& a, const ViewPose& b) {
    const double angle = std::max(std::abs(b.primary_deg - a.primary_deg), std::abs(b.secondary_deg - a.secondary_deg));
    const double seconds = std::max(angle / plan.rotation_deg_per_s, 0.5);
    const int steps = std::max(1, static_cast<int>(std::ceil(seconds * plan.carm_rate_hz)));
    const std::int64_t t0 = t;
    for (int k = 1; k <= steps; ++k) {
      const double f = static_cast<double>(k) / steps;
      t = t0 + static_cast<std::int64_t>(std::llround(seconds * 1e9 * f));
      const ViewPose p{a.primary_deg + f * (b.primary_deg - a.primary_deg), a.secondary_deg + f * (b.secondary_deg - a.secondary_deg),
                       a.table_mm + f * (b.table_mm - a.table_mm)};
      sample(k == steps ? b : p, false, k < steps);
    }
    hold(b, false, t + kSecond / 4);  // the operator waits for the arm to settle
  };
  run(poses[0], "fluoro", plan.fluoro_fps, plan.fluoro_seconds);
  move(poses[0], poses[1]);
  run(poses[1], "fluoro", plan.fluoro_fps, plan.fluoro_seconds);
  move(poses[1], poses[2]);
  run(poses[2], "fluoro", plan.fluoro_fps, plan.fluoro_seconds, plan.zoom_change ? 2 : 0);
  hold(poses[2], false, t + kSecond);
  run(poses[2], "dsa", plan.dsa_fps, plan.dsa_seconds);

  // Render: the noise-free image once per (view, contrast), a detector readout per frame.
  std::map<std::pair<std::size_t, double>, XRayExpected> cache;
  session::SessionTruth truth{"patient/truth/scene.json", "patient/device.mrk.json", "truth/ostia_2d.csv", {}, std::nullopt};
  char name[32];
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const FramePlan& f = frames[i];
    const session::CArmSample& c = s.carm[f.carm];
    const geometry::CArmView view = session::view_of(s, c);
    const Eigen::Matrix4d T = session::patient_to_carm(s, c);
    // One expected image per C-arm sample (each run has its own) and contrast level.
    const auto key = std::make_pair(f.carm, f.contrast);
    auto it = cache.find(key);
    if (it == cache.end()) {
      XRayContent content;
      content.body = &body;
      content.patient_to_world = T;
      content.contrast = vessels;
      content.contrast_fraction = f.contrast;
      content.wires = {patient.preoperative.device};
      it = cache.emplace(key, expected_xray(view, content, plan.xray)).first;
    }
    session::FrameRecord record;
    record.frame = static_cast<std::int64_t>(i) + 1;
    record.timestamp_ns = f.t;
    record.source = f.source;
    std::snprintf(name, sizeof name, "%06zu.png", i + 1);
    record.file = name;
    cv::Mat image = detect(it->second.quanta, plan.xray, plan.seed * 1'000'003ULL + i);
    if (plan.video_out) {
      char counter[32];
      std::snprintf(counter, sizeof counter, "%s %06zu", f.source == "dsa" ? "DSA" : "FL", i + 1);
      image = monitor_picture(image, *plan.video_out,
                              {"SIM PATIENT " + std::to_string(plan.seed),
                               angulation_text(c.primary_deg, c.secondary_deg), counter, "80 kV  3.2 mA"});
    }
    session::write_session_frame(dir, record, image);
    s.frames.push_back(record);
    const geometry::ProjectionMatrix P = geometry::registered(geometry::projection_matrix(view), T);
    for (const auto& lm : patient.truth.landmarks)
      if (const auto px = geometry::project(P, lm.position_lps);
          px && px->x() >= -0.5 && px->y() >= -0.5 && px->x() <= view.detector_cols - 0.5 && px->y() <= view.detector_rows - 0.5)
        truth.ostia.push_back({record.frame, lm.label, *px});
    if (progress) progress(i + 1, frames.size());
  }
  // What the node is given: the true registration composed with the residual, so the
  // scene it draws is the true anatomy moved by the residual.
  if (!out.residual.is_identity()) {
    truth.ct_to_carm = s.ct_to_carm;
    s.ct_to_carm = s.ct_to_carm * out.residual.transform();
  }
  s.truth = std::move(truth);
  session::write_session_files(dir, s);
  out.render_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace evar::sim
