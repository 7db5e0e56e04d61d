// Rendering simulated sessions (issue 4's target: a session of a few hundred 1024 x 1024
// frames in well under a minute on this machine). A settled view's noise-free image is
// computed once (BM_XRayExpected), then each frame is one detector readout (BM_XRayDetect)
// and one 16-bit PNG write (BM_SessionFrameWrite).
#include <benchmark/benchmark.h>

#include <filesystem>

#include "evar/session/session.hpp"
#include "evar/sim/synthetic_patient.hpp"
#include "evar/sim/xray_render.hpp"

using namespace evar;

namespace {

struct Scene {
  sim::SyntheticPatient patient = sim::make_patient(3);
  sim::BodyPhantom body = sim::default_body_phantom(3);
  geometry::CArmView view;
  sim::XRayContent content;
  Scene() {
    view.primary_angle_deg = 25;
    view.secondary_angle_deg = -15;
    view.source_to_detector_mm = 1200;
    view.source_to_isocenter_mm = 800;
    view.detector_cols = view.detector_rows = 1024;
    view.row_spacing_mm = view.col_spacing_mm = 0.3;
    content.body = &body;
    content.patient_to_world(2, 3) = -50.0;
    for (const auto& v : patient.truth.vessels) content.contrast.push_back(&v.mesh);
    content.wires = {patient.preoperative.device};
  }
};

Scene& scene() {
  static Scene s;
  return s;
}

void BM_XRayExpected(benchmark::State& state) {
  auto& s = scene();
  s.content.contrast_fraction = static_cast<double>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(sim::expected_xray(s.view, s.content).quanta.data);
}
BENCHMARK(BM_XRayExpected)->Arg(0)->Arg(1)->ArgName("contrast")->Unit(benchmark::kMillisecond);

void BM_XRayDetect(benchmark::State& state) {
  auto& s = scene();
  s.content.contrast_fraction = 0.0;
  const auto e = sim::expected_xray(s.view, s.content);
  std::uint64_t seed = 1;
  for (auto _ : state) benchmark::DoNotOptimize(sim::detect(e.quanta, {}, ++seed).data);
}
BENCHMARK(BM_XRayDetect)->Unit(benchmark::kMillisecond);

void BM_SessionFrameWrite(benchmark::State& state) {
  auto& s = scene();
  const cv::Mat image = sim::detect(sim::expected_xray(s.view, s.content).quanta, {}, 1);
  const auto dir = std::filesystem::temp_directory_path() / "evar_bench_frames";
  session::FrameRecord r{1, 0, "fluoro", "bench.png"};
  for (auto _ : state) session::write_session_frame(dir, r, image);
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_SessionFrameWrite)->Unit(benchmark::kMillisecond);

}  // namespace
