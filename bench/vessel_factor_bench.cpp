// The aorta's ARAP system of the example scene (surface + skeleton terms + registration
// tether, as SceneDeformer builds it) and its factorization for the first containment
// round's constraint set, at the three scene resolutions:
//
//   vessel_system/<n>       ArapSystem construction (assembly + AMD ordering; SceneDeformer
//                           does this once per vessel);
//   vessel_factor/<n>       ArapSolver(system, constrained): free block + numeric factorization
//                           (what each deform() call pays per round);
//   vessel_free_block/<n>   for comparison, the bd2df38 path: the free block A_FF ordered
//                           by Eigen's own AMD and factored (AMD + symbolic + numeric);
//   vessel_iteration/<n>    one local/global iteration of that constraint set, Anderson on
//                           (iterate_ms / iterations over 20 that never converge);
//   vessel_local_step/<n>   its parts: the local step with b(R) in the same pass, from the
//   vessel_solve_xyz/<n>    rotations of the previous step, and the triangular solve.
//
// The set-up mirrors SceneDeformer's private make_model() with default DeformOptions; the
// deform benchmarks time the product code itself.
#include <benchmark/benchmark.h>

#include <Eigen/SparseCholesky>
#include <chrono>
#include <map>
#include <memory>

#include "bench_problems.hpp"
#include "evar/deform/control_points.hpp"
#include "evar/deform/registration_tether.hpp"
#include "evar/deform/scene_deformation.hpp"
#include "evar/deform/skeleton.hpp"
#include "evar/geometry/ray_caster.hpp"

using namespace evar;
using bench::avg;
using Clock = std::chrono::steady_clock;

namespace {

struct AortaProblem {
  deform::ArapTerms terms;
  deform::ArapTether tether;
  std::shared_ptr<const deform::ArapSystem> system;
  std::vector<int> constrained;  ///< handle vertices of the first round
  geometry::Vertices targets;     ///< their targets
  int vertices = 0;
};

const AortaProblem& aorta(int aorta_vertices) {
  static std::map<int, std::unique_ptr<AortaProblem>> cache;
  auto& slot = cache[aorta_vertices];
  if (slot) return *slot;
  const auto& sp = bench::example_scene(aorta_vertices);
  const geometry::Vessel* v = nullptr;
  for (const auto& x : sp.scene.vessels)
    if (x.kind == geometry::VesselKind::Aorta) v = &x;
  const deform::DeformOptions opt;
  const auto& mesh = v->mesh.mesh;
  const geometry::RayCaster caster(mesh);
  const auto skeleton = deform::build_skeleton(caster, v->centerline, opt.skeleton);
  const int n = static_cast<int>(mesh.V.rows());
  const int centres = static_cast<int>(skeleton.centres.size());
  auto p = std::make_unique<AortaProblem>();
  p->vertices = n;
  p->terms = deform::surface_arap_terms(mesh.V, deform::cotangent_weights(mesh), n + centres);
  deform::append_skeleton_terms(p->terms, mesh, skeleton, n, opt.skeleton.weight);
  p->tether = deform::registration_tether(mesh, n + centres, opt.tether_length_mm);
  p->system = std::make_shared<const deform::ArapSystem>(p->terms, opt.arap, p->tether);
  auto control = opt.control;
  control.device_thickness_mm = sp.scene.device_thickness_mm;
  const auto handles =
      deform::select_control_points(mesh, caster, v->centerline, deform::radius_profile(skeleton), sp.example.device, control);
  const auto targets = deform::handle_vertex_targets(mesh, handles);
  p->targets.resize(static_cast<Eigen::Index>(targets.size()), 3);
  for (const auto& [k, target] : targets) {
    p->targets.row(static_cast<Eigen::Index>(p->constrained.size())) = target.transpose();
    p->constrained.push_back(k);
  }
  slot = std::move(p);
  return *slot;
}

void set_common(benchmark::State& state, const AortaProblem& p) {
  state.counters["vertices"] = p.vertices;
  state.counters["unknowns"] = p.system->num_unknowns();
  state.counters["constrained"] = static_cast<double>(p.constrained.size());
}

void BM_VesselSystem(benchmark::State& state, int aorta_vertices) {
  const auto& p = aorta(aorta_vertices);
  double assemble = 0, ordering = 0, cpu = 0;
  for (auto _ : state) {
    auto terms = p.terms;  // copies outside the timing
    auto tether = p.tether;
    const double c0 = bench::cpu_ms();
    const auto t0 = Clock::now();
    const deform::ArapSystem system(std::move(terms), deform::ArapOptions{}, std::move(tether));
    const auto t1 = Clock::now();
    cpu += bench::cpu_ms() - c0;
    state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
    assemble += system.assemble_ms();
    ordering += system.ordering_ms();
  }
  set_common(state, p);
  state.counters["assemble_ms"] = avg(assemble);
  state.counters["ordering_ms"] = avg(ordering);
  state.counters["cpu_ms"] = avg(cpu);
  state.counters["nnz_A"] = static_cast<double>(p.system->matrix().nonZeros());
}

void BM_VesselFactor(benchmark::State& state, int aorta_vertices) {
  const auto& p = aorta(aorta_vertices);
  double free_block = 0, factor = 0, cpu = 0;
  for (auto _ : state) {
    auto constrained = p.constrained;
    const double c0 = bench::cpu_ms();
    const auto t0 = Clock::now();
    const deform::ArapSolver solver(p.system, std::move(constrained));
    const auto t1 = Clock::now();
    cpu += bench::cpu_ms() - c0;
    state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
    free_block += solver.assemble_ms() - p.system->assemble_ms();
    factor += solver.factor_ms();
  }
  set_common(state, p);
  state.SetLabel("eigen, system ordering");
  state.counters["free_block_ms"] = avg(free_block);
  state.counters["factor_ms"] = avg(factor);
  state.counters["cpu_ms"] = avg(cpu);
  const deform::ArapSolver solver(p.system, p.constrained, deform::ConstraintMethod::Refactor);
  state.counters["nnz_L"] = static_cast<double>(solver.factor_nonzeros());
}

void BM_VesselFreeBlock(benchmark::State& state, int aorta_vertices) {
  const auto& p = aorta(aorta_vertices);
  bench::time_free_block_factor(state, bench::free_block(*p.system, p.constrained));
  set_common(state, p);
}

void BM_VesselIteration(benchmark::State& state, int aorta_vertices) {
  const auto& p = aorta(aorta_vertices);
  deform::ArapOptions opt;
  opt.max_iterations = 20;
  opt.tolerance_mm = 1e-12;  // never reached: every run does all 20
  const deform::ArapSolver solver(std::make_shared<const deform::ArapSystem>(p.terms, opt, p.tether), p.constrained);
  double per_iter = 0;
  for (auto _ : state) {
    const auto result = solver.solve(p.targets);
    const double ms = result.iterate_ms / std::max(result.iterations, 1);
    state.SetIterationTime(ms / 1e3);
    per_iter += ms;
  }
  set_common(state, p);
  state.counters["per_iter_ms"] = avg(per_iter);
  state.SetLabel(solver.method() == deform::ConstraintMethod::Capacitance ? "capacitance" : "refactor");
}

// A deformed configuration and its rotations, as the iterations meet them.
struct Configuration {
  geometry::Vertices X;
  std::vector<Eigen::Matrix3d> R;
};
Configuration configuration(const AortaProblem& p) {
  const deform::ArapSolver solver(p.system, p.constrained);
  Configuration c{solver.solve(p.targets).X, std::vector<Eigen::Matrix3d>(static_cast<std::size_t>(p.terms.num_cells),
                                                                          Eigen::Matrix3d::Identity())};
  p.system->local_step(c.X, c.R);
  return c;
}

void BM_VesselLocalStep(benchmark::State& state, int aorta_vertices) {
  const auto& p = aorta(aorta_vertices);
  const auto c = configuration(p);
  std::vector<Eigen::Matrix3d> R;
  geometry::Vertices b;
  for (auto _ : state) benchmark::DoNotOptimize(p.system->local_step(c.X, c.R, R, &b));
  set_common(state, p);
}

void BM_VesselSolveXyz(benchmark::State& state, int aorta_vertices) {
  const auto& p = aorta(aorta_vertices);
  const auto c = configuration(p);
  geometry::Vertices b;
  p.system->right_hand_side(c.R, b);
  const Eigen::MatrixXd B = b;
  const auto* A = p.system->prefactored();
  if (!A) {
    state.SkipWithError("the aorta's system is not prefactored");
    return;
  }
  for (auto _ : state) benchmark::DoNotOptimize(A->solve(B));
  set_common(state, p);
  state.counters["nnz_L"] = static_cast<double>(A->factor_nonzeros());
}

}  // namespace

BENCHMARK_CAPTURE(BM_VesselIteration, 7500, 7500)->Iterations(5)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_VesselLocalStep, 7500, 7500)->Iterations(50)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_VesselSolveXyz, 7500, 7500)->Iterations(100)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_VesselSystem, 7500, 7500)->Iterations(20)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_VesselFactor, 7500, 7500)->Iterations(20)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_VesselFreeBlock, 7500, 7500)->Iterations(20)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_VesselSystem, 30000, 30000)->Iterations(5)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_VesselFactor, 30000, 30000)->Iterations(5)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_VesselFreeBlock, 30000, 30000)->Iterations(5)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_VesselSystem, 120000, 120000)->Iterations(2)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_VesselFactor, 120000, 120000)->Iterations(2)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_VesselFreeBlock, 120000, 120000)->Iterations(2)->Unit(benchmark::kMillisecond);
