// The live roadmap's cost per frame (overlay::FrameCompositor) on a 1024 x 1024 Mono16
// frame with the example scene's three vessels: with the C-arm still (the layer cached,
// only window/level and the blend) and when the layer must be drawn again (a new model or
// a new angulation: two renders at supersample 2).
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "evar/geometry/carm_projection.hpp"
#include "evar/overlay/frame_compositor.hpp"
#include "evar/sim/example_scene.hpp"

namespace {

using namespace evar;

struct Setup {
  geometry::CArmView view;
  std::shared_ptr<overlay::RoadmapModel> model = std::make_shared<overlay::RoadmapModel>();
  std::vector<std::uint16_t> pixels;
  overlay::GreyFrame frame;
  Setup() {
    view.source_to_detector_mm = 1200;
    view.source_to_isocenter_mm = 800;
    view.detector_cols = view.detector_rows = 1024;
    view.row_spacing_mm = view.col_spacing_mm = 0.3;
    const auto scene = sim::make_example_scene({});
    // The vessels centred on the isocenter, as a registration puts them.
    Eigen::AlignedBox3d box;
    for (const auto& v : scene.vessels)
      for (Eigen::Index i = 0; i < v.mesh.V.rows(); ++i) box.extend(v.mesh.V.row(i).transpose());
    const Eigen::RowVector3d centre = box.center().transpose();
    for (const auto& v : scene.vessels) {
      geometry::TriangleMesh m = v.mesh;
      m.V.rowwise() -= centre;
      model->initial.push_back(m);
      model->adapted.push_back(m);
    }
    for (auto l : scene.landmarks) {
      l.position_lps -= centre.transpose();
      model->initial_landmarks.push_back(l);
      model->adapted_landmarks.push_back(l);
    }
    pixels.resize(1024 * 1024);
    for (std::size_t i = 0; i < pixels.size(); ++i) pixels[i] = static_cast<std::uint16_t>(1000 + (i * 7919) % 3000);
    frame = {1024, 1024, 2048, 16, reinterpret_cast<const std::uint8_t*>(pixels.data())};
  }
};

void BM_ComposeStill(benchmark::State& state) {
  Setup s;
  const auto P = geometry::projection_matrix(s.view);
  overlay::FrameCompositor c;
  const overlay::StatusBlock status{{"LAO 0  CRA 0  SID 1200 mm", "model: adapted", "roadmap: both"}, {}};
  c.compose(s.frame, &P, s.model, overlay::RoadmapMode::Both, status);
  for (auto _ : state) benchmark::DoNotOptimize(c.compose(s.frame, &P, s.model, overlay::RoadmapMode::Both, status));
}
BENCHMARK(BM_ComposeStill)->Unit(benchmark::kMillisecond);

void BM_ComposeNewLayer(benchmark::State& state) {
  Setup s;
  overlay::FrameCompositor c;
  int k = 0;
  for (auto _ : state) {
    s.view.primary_angle_deg = (k++ % 2) ? 1.0 : 0.0;  // a different projection every frame
    const auto P = geometry::projection_matrix(s.view);
    benchmark::DoNotOptimize(c.compose(s.frame, &P, s.model, overlay::RoadmapMode::Both, {}));
  }
}
BENCHMARK(BM_ComposeNewLayer)->Unit(benchmark::kMillisecond);

}  // namespace
