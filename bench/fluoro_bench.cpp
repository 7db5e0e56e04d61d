// Device segmentation of a 1024 x 1024 frame and two-view reconstruction (issue 3's speed
// target: both together under 30 ms on one core). Frames are rendered once, outside the
// timing, by sim::render_fluoro: a 0.89 mm guidewire over the schematic spine, 0.3 mm pixels.
#include <benchmark/benchmark.h>

#include <map>

#include "evar/geometry/device_segmentation.hpp"
#include "evar/geometry/two_view_reconstruction.hpp"
#include "evar/sim/fluoro_render.hpp"

using namespace evar;

namespace {

struct Pair {
  geometry::CArmView view[2];
  geometry::ProjectionMatrix P[2];
  sim::FluoroFrame frame[2];
  geometry::SegmentationOptions options;
};

const Pair& pair_of(int size_px) {
  static std::map<int, Pair> cache;
  auto it = cache.find(size_px);
  if (it != cache.end()) return it->second;
  Pair p;
  const geometry::Polyline wire = sim::iliac_guidewire();
  const double spacing = 0.3 * 1024.0 / size_px;
  for (int k = 0; k < 2; ++k) {
    auto& v = p.view[k];
    v.primary_angle_deg = k == 0 ? 30 : -30;
    v.secondary_angle_deg = k == 0 ? 5 : -5;
    v.source_to_detector_mm = 1200;
    v.source_to_isocenter_mm = 800;
    v.detector_cols = v.detector_rows = size_px;
    v.row_spacing_mm = v.col_spacing_mm = spacing;
    p.P[k] = geometry::projection_matrix(v);
    sim::FluoroOptions o;
    o.seed = static_cast<std::uint64_t>(k + 1);
    p.frame[k] = sim::render_fluoro(p.P[k], v, {wire}, o);
  }
  p.options.device_width_px = geometry::device_shadow_width_px(p.view[0], 0.89);
  return cache.emplace(size_px, std::move(p)).first->second;
}

void BM_Segment(benchmark::State& state) {
  const auto& p = pair_of(static_cast<int>(state.range(0)));
  double ridge = 0, path = 0;
  for (auto _ : state) {
    const auto d = geometry::segment_device(p.frame[0].image, p.options);
    if (!d.found) state.SkipWithError(d.reason.c_str());
    ridge += d.ridge_ms;
    path += d.path_ms;
  }
  state.counters["ridge_ms"] = ridge / static_cast<double>(state.iterations());
  state.counters["path_ms"] = path / static_cast<double>(state.iterations());
}

void BM_Reconstruct(benchmark::State& state) {
  const auto& p = pair_of(static_cast<int>(state.range(0)));
  const auto a = geometry::segment_device(p.frame[0].image, p.options), b = geometry::segment_device(p.frame[1].image, p.options);
  for (auto _ : state) benchmark::DoNotOptimize(geometry::reconstruct_two_view(a.points, p.P[0], b.points, p.P[1]));
  state.counters["points_1"] = static_cast<double>(a.points.size());
  state.counters["points_2"] = static_cast<double>(b.points.size());
}

// What a new view pair costs: the second view is segmented when it arrives, the first was
// segmented before; so one segmentation plus the reconstruction.
void BM_SegmentAndReconstruct(benchmark::State& state) {
  const auto& p = pair_of(static_cast<int>(state.range(0)));
  const auto a = geometry::segment_device(p.frame[0].image, p.options);
  for (auto _ : state) {
    const auto b = geometry::segment_device(p.frame[1].image, p.options);
    benchmark::DoNotOptimize(geometry::reconstruct_two_view(a.points, p.P[0], b.points, p.P[1]));
  }
}

}  // namespace

BENCHMARK(BM_Segment)->Arg(512)->Arg(1024)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Reconstruct)->Arg(1024)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SegmentAndReconstruct)->Arg(1024)->Unit(benchmark::kMillisecond);

#include <opencv2/imgproc.hpp>
namespace {
void BM_OpenCvBlur(benchmark::State& state) {
  cv::Mat f(1024, 1024, CV_32F), g;
  cv::randu(f, 0, 1);
  const double sigma = static_cast<double>(state.range(0)) / 10.0;
  for (auto _ : state) cv::GaussianBlur(f, g, cv::Size(0, 0), sigma, sigma, cv::BORDER_REFLECT);
}
}  // namespace
BENCHMARK(BM_OpenCvBlur)->Arg(10)->Arg(22)->Arg(31)->Unit(benchmark::kMillisecond);
