// deform_scene on the example aorto-iliac scene (sim::make_example_scene, converted in
// memory to a geometry::Scene), at the default resolution (aorta ~7.5k vertices, iliacs
// ~3.5k) and scaled 4x and 16x (aorta ~30k and ~120k). Per-vessel stage timings from the
// VesselReport structs are reported as counters "<vessel>.<stage>_ms"; "total_ms" is
// SceneDeformation::total_ms (everything, including handle binding, erasure, landmarks).
#include <benchmark/benchmark.h>

#include <map>
#include <stdexcept>

#include "bench_problems.hpp"
#include "evar/deform/scene_deformation.hpp"

using namespace evar;
using bench::avg;

namespace {

void BM_DeformScene(benchmark::State& state, int aorta_vertices, int backend_arg) {
  deform::DeformOptions opt;
  opt.arap.backend = bench::backend_arg(backend_arg);
  if (!bench::backend_usable(state, opt.arap.backend)) return;
  const auto& sp = bench::example_scene(aorta_vertices);
  std::map<std::string, double> sums;
  double total = 0, cpu = 0;
  for (auto _ : state) {
    const double c0 = bench::cpu_ms();
    const auto out = deform::deform_scene(sp.scene, sp.example.device, opt);
    cpu += bench::cpu_ms() - c0;
    state.SetIterationTime(out.total_ms / 1e3);
    total += out.total_ms;
    for (const auto& r : out.reports) {
      const auto& t = r.timings;
      sums[r.name + ".weights_ms"] += t.weights_ms;
      sums[r.name + ".control_points_ms"] += t.control_points_ms;
      sums[r.name + ".skeleton_ms"] += t.skeleton_ms;
      sums[r.name + ".factor_ms"] += t.factor_ms;
      sums[r.name + ".iterate_ms"] += t.iterate_ms;
      sums[r.name + ".total_ms"] += t.total_ms;
      sums[r.name + ".iterations"] += r.iterations;
      sums[r.name + ".rounds"] += r.rounds;
      sums[r.name + ".converged"] += r.converged ? 1 : 0;
      sums[r.name + ".vertices"] += r.vertices;
      sums[r.name + ".constrained"] += r.constrained_vertices;
    }
  }
  for (const auto& [name, sum] : sums) state.counters[name] = avg(sum);
  state.counters["total_ms"] = avg(total);
  state.counters["cpu_ms"] = avg(cpu);  // all threads (Embree builds its BVHs with TBB)
  state.SetLabel(bench::backend_label(opt.arap.backend));
}

// How far a stopping rule leaves each vessel from the fixed point of the whole
// deformation: the same deform_scene run with a 1e-7 mm tolerance is the reference.
// Handles are re-selected between containment rounds, so the counters also show the
// handle counts of both runs (equal counts: the two runs solved the same problem).
const deform::SceneDeformation& deform_reference() {
  static const deform::SceneDeformation ref = [] {
    deform::DeformOptions tight;
    tight.arap.tolerance_mm = 1e-7;
    tight.arap.max_iterations = 100000;
    auto out = deform::deform_scene(bench::example_scene(7500).scene, bench::example_scene(7500).example.device, tight);
    for (const auto& r : out.reports)
      if (!r.converged) throw std::runtime_error("deform fixed-point reference: " + r.name + " did not converge");
    return out;
  }();
  return ref;
}

void BM_DeformFixedPoint(benchmark::State& state, double tolerance_mm) {
  const auto& sp = bench::example_scene(7500);
  deform::DeformOptions opt;
  opt.arap.tolerance_mm = tolerance_mm;
  opt.arap.max_iterations = 100000;
  const auto& ref = deform_reference();
  std::map<std::string, double> sums;
  double total = 0, cpu = 0;
  for (auto _ : state) {
    const double c0 = bench::cpu_ms();
    const auto out = deform::deform_scene(sp.scene, sp.example.device, opt);
    cpu += bench::cpu_ms() - c0;
    state.SetIterationTime(out.total_ms / 1e3);
    total += out.total_ms;
    for (std::size_t i = 0; i < out.vessels.size(); ++i) {
      const auto& name = out.reports[i].name;
      sums[name + ".max_dist_mm"] += bench::max_row_distance(out.vessels[i].mesh.V, ref.vessels[i].mesh.V);
      sums[name + ".iterations"] += out.reports[i].iterations;
      sums[name + ".total_ms"] += out.reports[i].timings.total_ms;
      sums[name + ".factor_ms"] += out.reports[i].timings.factor_ms;
      sums[name + ".iterate_ms"] += out.reports[i].timings.iterate_ms;
      sums[name + ".ref_iterations"] += ref.reports[i].iterations;
      sums[name + ".control_points"] += out.reports[i].control_points;
      sums[name + ".ref_control_points"] += ref.reports[i].control_points;
      sums[name + ".rounds"] += out.reports[i].rounds;
    }
  }
  for (const auto& [name, sum] : sums) state.counters[name] = avg(sum);
  state.counters["total_ms"] = avg(total);
  state.counters["cpu_ms"] = avg(cpu);
}

}  // namespace

BENCHMARK_CAPTURE(BM_DeformScene, 7500/eigen, 7500, 0)->Iterations(5)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformScene, 7500/cholmod, 7500, 1)->Iterations(5)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformScene, 30000/eigen, 30000, 0)->Iterations(2)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformScene, 30000/cholmod, 30000, 1)->Iterations(2)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformScene, 120000/eigen, 120000, 0)->Iterations(1)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformScene, 120000/cholmod, 120000, 1)->Iterations(1)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformFixedPoint, 7500/default_0.01, 0.01)->Iterations(3)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformFixedPoint, 7500/tolerance_0.001, 1e-3)->Iterations(3)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformFixedPoint, 7500/tolerance_0.0001, 1e-4)->Iterations(3)->UseManualTime()->Unit(benchmark::kMillisecond);
