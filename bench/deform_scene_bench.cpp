// The deformation stage on the example aorto-iliac scene (sim::make_example_scene,
// converted in memory by sim::to_scene), at the default resolution (aorta ~7.5k vertices,
// iliacs ~3.5k) and scaled 4x and 16x (aorta ~30k and ~120k):
//
//   BM_DeformScene      cold: deform_scene() = SceneDeformer construction (BVH, skeleton,
//                       weights, terms, tether, assembly, ordering per vessel) + deform();
//   BM_DeformWarm       warm: the SceneDeformer is built once outside the timing; each
//                       iteration is one deform(device) (control points, numeric
//                       factorization, iterations, binding, erasure, landmarks); at 30k
//                       and 120k the vessels are solved on proxies (mesh_proxy.hpp);
//   BM_DeformWarmOwnMesh the same with every mesh solved as it is, for comparison;
//   BM_DeformFixedPoint warm deform at a given tolerance against a tightly converged
//                       reference (tolerance 1e-6 mm): distance per vessel and time;
//   BM_DeformSequence   a moving device, frame after frame, each frame started from
//                       scratch or from the previous frame's result, against per-frame
//                       references.
//
// Per-vessel counters "<vessel>.<stage>_ms" come from the VesselReport structs. In a warm
// call, "<vessel>.call_ms" = control_points + factor + iterate (what the call spent on that
// vessel); the reports' own total_ms also adds the precomputation's weights and skeleton
// times (the vessel's cold cost). "total_ms" is SceneDeformation::total_ms (for
// deform_scene: precomputation + the call; for a warm call: the call's wall time).
//
// One thread, as the targets are stated: the iliacs are solved one after the other
// (DeformOptions::parallel_iliacs off). Pinned to one core, two iliac threads would each be
// charged the other's time. BM_DeformWarm's "two_threads" rows are the node's setting.
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <tuple>

#include "bench_problems.hpp"
#include "evar/deform/scene_deformation.hpp"

using namespace evar;
using bench::avg;

namespace {

// Per-vessel work of one call: what deform() itself spends (precomputation excluded).
double call_ms(const deform::VesselReport& r) {
  return r.timings.control_points_ms + r.timings.factor_ms + r.timings.iterate_ms;
}

// Per-vessel counters of one run, summed over the benchmark's iterations.
void add_reports(std::map<std::string, double>& sums, const deform::SceneDeformation& out, bool warm) {
  for (const auto& r : out.reports) {
    const auto& t = r.timings;
    if (!warm) {
      sums[r.name + ".weights_ms"] += t.weights_ms;
      sums[r.name + ".skeleton_ms"] += t.skeleton_ms;
      sums[r.name + ".total_ms"] += t.total_ms;
    }
    sums[r.name + ".control_points_ms"] += t.control_points_ms;
    sums[r.name + ".factor_ms"] += t.factor_ms;
    sums[r.name + ".iterate_ms"] += t.iterate_ms;
    sums[r.name + ".call_ms"] += call_ms(r);
    sums[r.name + ".iterations"] += r.iterations;
    sums[r.name + ".rounds"] += r.rounds;
    sums[r.name + ".converged"] += r.converged ? 1 : 0;
    sums[r.name + ".vertices"] += r.vertices;
    sums[r.name + ".constrained"] += r.constrained_vertices;
    sums[r.name + ".control_points"] += r.control_points;
  }
}

// Time per iteration of a vessel, approximately: each round does one initial guess (a
// global and a local step, or a warm start) and `iterations` local/global steps.
void add_per_iteration(benchmark::State& state, const std::map<std::string, double>& sums) {
  for (const char* v : {"aorta", "iliac_right"}) {
    const std::string n(v);
    const auto it = sums.find(n + ".iterations");
    if (it == sums.end() || it->second <= 0) continue;
    state.counters[n + ".per_iter_ms"] =
        benchmark::Counter(sums.at(n + ".iterate_ms") / (it->second + sums.at(n + ".rounds")));
  }
}

// --- cold: deform_scene (precomputation + deform) ---------------------------------------
void BM_DeformScene(benchmark::State& state, int aorta_vertices, int backend_arg) {
  deform::DeformOptions opt;
  opt.arap.backend = bench::backend_arg(backend_arg);
  opt.parallel_iliacs = false;
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
    add_reports(sums, out, false);
  }
  for (const auto& [name, sum] : sums) state.counters[name] = avg(sum);
  add_per_iteration(state, sums);
  state.counters["total_ms"] = avg(total);
  state.counters["cpu_ms"] = avg(cpu);  // all threads
  state.SetLabel(bench::backend_label(opt.arap.backend));
}

// A SceneDeformer per (size, backend, tolerance), built once and warmed up by one untimed
// deform() call (first use of the low-quality BVH build path, allocator).
struct Warm {
  std::unique_ptr<deform::SceneDeformer> deformer;
  double construct_ms = 0.0;
};
// `proxy_edge_mm` < 0: the default (fine meshes solved on proxies); 0: every mesh as it is.
// `parallel`: the iliacs on threads of their own (the node's setting).
const Warm& warm_deformer(int aorta_vertices, deform::CholeskyBackend backend, double tolerance_mm,
                          double proxy_edge_mm = -1.0, bool parallel = false) {
  static std::map<std::tuple<int, int, double, double, bool>, std::unique_ptr<Warm>> cache;
  auto& slot = cache[{aorta_vertices, static_cast<int>(backend), tolerance_mm, proxy_edge_mm, parallel}];
  if (!slot) {
    const auto& sp = bench::example_scene(aorta_vertices);
    deform::DeformOptions opt;
    opt.arap.backend = backend;
    opt.arap.tolerance_mm = tolerance_mm;  // everything else default (at most 500 iterations)
    if (proxy_edge_mm >= 0.0) opt.proxy_edge_mm = proxy_edge_mm;
    opt.parallel_iliacs = parallel;
    slot = std::make_unique<Warm>();
    slot->deformer = std::make_unique<deform::SceneDeformer>(sp.scene, opt);
    slot->construct_ms = slot->deformer->precompute_ms();
    slot->deformer->deform(sp.example.device);
  }
  return *slot;
}

// Times deform(device) on a prebuilt SceneDeformer for `state`'s iterations, summing the
// per-vessel report counters into `sums`; `each` sees every result (extra counters).
template <typename Each>
void time_warm_deform(benchmark::State& state, const deform::SceneDeformer& deformer,
                      const geometry::Polyline& device, std::map<std::string, double>& sums, Each each) {
  double total = 0, cpu = 0;
  for (auto _ : state) {
    const double c0 = bench::cpu_ms();
    const auto out = deformer.deform(device);
    cpu += bench::cpu_ms() - c0;
    state.SetIterationTime(out.total_ms / 1e3);
    total += out.total_ms;
    add_reports(sums, out, true);
    each(out);
  }
  for (const auto& [name, sum] : sums) state.counters[name] = avg(sum);
  add_per_iteration(state, sums);
  state.counters["total_ms"] = avg(total);  // wall time of deform() per call
  state.counters["cpu_ms"] = avg(cpu);
}

// --- warm: deform(device) on a prebuilt SceneDeformer ----------------------------------
void BM_DeformWarm(benchmark::State& state, int aorta_vertices, int backend_arg, bool parallel = false) {
  const auto backend = bench::backend_arg(backend_arg);
  if (!bench::backend_usable(state, backend)) return;
  const auto& sp = bench::example_scene(aorta_vertices);
  const auto& w = warm_deformer(aorta_vertices, backend, deform::ArapOptions{}.tolerance_mm, -1.0, parallel);
  std::map<std::string, double> sums;
  time_warm_deform(state, *w.deformer, sp.example.device, sums, [](const deform::SceneDeformation&) {});
  state.counters["precompute_ms"] = w.construct_ms;  // the SceneDeformer constructor (once)
  state.SetLabel(bench::backend_label(backend) + (parallel ? ", warm, iliacs on two threads" : ", warm"));
}

// The same with every mesh solved as it is (no proxy for fine meshes), for comparison.
void BM_DeformWarmOwnMesh(benchmark::State& state, int aorta_vertices) {
  const auto& sp = bench::example_scene(aorta_vertices);
  const auto& w = warm_deformer(aorta_vertices, deform::CholeskyBackend::EigenLDLT, deform::ArapOptions{}.tolerance_mm, 0.0);
  std::map<std::string, double> sums;
  time_warm_deform(state, *w.deformer, sp.example.device, sums, [](const deform::SceneDeformation&) {});
  state.counters["precompute_ms"] = w.construct_ms;
  state.SetLabel("eigen, warm, every mesh solved as it is");
}

// --- distance to the fixed point (warm) -----------------------------------------------
// Reference: the same scene deformed with a 1e-6 mm tolerance. Handles are re-selected
// between containment rounds, so the counters also carry the handle counts of both runs
// (equal counts: the two runs solved the same problems).
constexpr double kReferenceTolerance = 1e-6;
const deform::SceneDeformation& deform_reference() {
  static const deform::SceneDeformation ref = [] {
    const auto& w = warm_deformer(7500, deform::CholeskyBackend::EigenLDLT, kReferenceTolerance);
    auto out = w.deformer->deform(bench::example_scene(7500).example.device);
    for (const auto& r : out.reports)
      if (!r.converged) throw std::runtime_error("deform fixed-point reference: " + r.name + " did not converge");
    return out;
  }();
  return ref;
}

void BM_DeformFixedPoint(benchmark::State& state, double tolerance_mm) {
  const auto& sp = bench::example_scene(7500);
  const auto& ref = deform_reference();
  const auto& w = warm_deformer(7500, deform::CholeskyBackend::EigenLDLT, tolerance_mm);
  std::map<std::string, double> sums;
  time_warm_deform(state, *w.deformer, sp.example.device, sums, [&](const deform::SceneDeformation& out) {
    for (std::size_t i = 0; i < out.vessels.size(); ++i) {
      const auto& name = out.reports[i].name;
      const auto d = (out.vessels[i].mesh.V - ref.vessels[i].mesh.V).rowwise().norm();
      sums[name + ".max_dist_mm"] += d.maxCoeff();
      sums[name + ".mean_dist_mm"] += d.mean();
      sums[name + ".ref_iterations"] += ref.reports[i].iterations;
      sums[name + ".ref_control_points"] += ref.reports[i].control_points;
    }
  });
  state.SetLabel("eigen, warm, tolerance " + std::to_string(tolerance_mm) + " mm, reference 1e-6 mm");
}

// --- a live sequence: each frame warm-started from the previous one ------------------
// The example device moved along a breathing-like loop (2 mm cranio-caudal, 0.5 mm
// left-right, kSequenceFrames frames per cycle), deformed frame after frame. Each frame's
// reference is its own deformation at 1e-6 mm from Laplacian editing.
constexpr int kSequenceFrames = 24;
geometry::Polyline sequence_device(int frame) {
  const double phase = 2.0 * 3.141592653589793 * frame / kSequenceFrames;
  geometry::Polyline device = bench::example_scene(7500).example.device;
  for (auto& p : device) p += Eigen::Vector3d(0.5 * std::sin(phase), 0.0, 2.0 * (1.0 - std::cos(phase)) / 2.0);
  return device;
}
const deform::SceneDeformation& sequence_reference(int frame) {
  static std::map<int, deform::SceneDeformation> refs;
  auto it = refs.find(frame);
  if (it == refs.end()) {
    const auto& w = warm_deformer(7500, deform::CholeskyBackend::EigenLDLT, kReferenceTolerance);
    it = refs.emplace(frame, w.deformer->deform(sequence_device(frame))).first;
  }
  return it->second;
}

void BM_DeformSequence(benchmark::State& state, double tolerance_mm, bool warm_start) {
  const auto& w = warm_deformer(7500, deform::CholeskyBackend::EigenLDLT, tolerance_mm);
  for (int k = 0; k < kSequenceFrames; ++k) sequence_reference(k);  // untimed
  std::map<std::string, double> sums;
  std::optional<deform::SceneDeformation> previous = w.deformer->deform(sequence_device(kSequenceFrames - 1));
  int frame = 0;
  double total = 0;
  for (auto _ : state) {
    auto out = w.deformer->deform(sequence_device(frame), warm_start ? &*previous : nullptr);
    state.SetIterationTime(out.total_ms / 1e3);
    total += out.total_ms;
    add_reports(sums, out, true);
    const auto& ref = sequence_reference(frame);
    for (std::size_t i = 0; i < out.vessels.size(); ++i) {
      const auto d = (out.vessels[i].mesh.V - ref.vessels[i].mesh.V).rowwise().norm();
      sums[out.reports[i].name + ".max_dist_mm"] += d.maxCoeff();
      sums[out.reports[i].name + ".same_handles"] += out.reports[i].control_points == ref.reports[i].control_points;
    }
    previous = std::move(out);
    frame = (frame + 1) % kSequenceFrames;
  }
  for (const auto& [name, sum] : sums) state.counters[name] = avg(sum);
  add_per_iteration(state, sums);
  state.counters["total_ms"] = avg(total);
  state.SetLabel(std::string(warm_start ? "warm start from the previous frame" : "every frame from scratch") +
                 ", tolerance " + std::to_string(tolerance_mm) + " mm");
}

}  // namespace

BENCHMARK_CAPTURE(BM_DeformSequence, 7500/cold_0.01, 0.01, false)->Iterations(48)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformSequence, 7500/warm_0.01, 0.01, true)->Iterations(48)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformSequence, 7500/cold_0.002, 2e-3, false)->Iterations(48)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformSequence, 7500/warm_0.002, 2e-3, true)->Iterations(48)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformScene, 7500/eigen, 7500, 0)->Iterations(5)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformScene, 7500/cholmod, 7500, 1)->Iterations(5)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformScene, 30000/eigen, 30000, 0)->Iterations(2)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformScene, 30000/cholmod, 30000, 1)->Iterations(2)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformScene, 120000/eigen, 120000, 0)->Iterations(1)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformScene, 120000/cholmod, 120000, 1)->Iterations(1)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformWarm, 7500/eigen, 7500, 0)->Iterations(10)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformWarm, 7500/eigen/two_threads, 7500, 0, true)->Iterations(10)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformWarm, 7500/cholmod, 7500, 1)->Iterations(10)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformWarm, 30000/eigen, 30000, 0)->Iterations(3)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformWarm, 30000/cholmod, 30000, 1)->Iterations(3)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformWarm, 120000/eigen, 120000, 0)->Iterations(2)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformWarm, 120000/cholmod, 120000, 1)->Iterations(2)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformWarmOwnMesh, 30000, 30000)->Iterations(3)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformWarmOwnMesh, 120000, 120000)->Iterations(2)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformFixedPoint, 7500/default_0.01, 0.01)->Iterations(10)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformFixedPoint, 7500/tolerance_0.005, 5e-3)->Iterations(10)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformFixedPoint, 7500/tolerance_0.002, 2e-3)->Iterations(10)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformFixedPoint, 7500/tolerance_0.001, 1e-3)->Iterations(10)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DeformFixedPoint, 7500/tolerance_0.0001, 1e-4)->Iterations(5)->UseManualTime()->Unit(benchmark::kMillisecond);
