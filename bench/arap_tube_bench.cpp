// ARAP on a bent tube (surface ARAP, no skeleton), stage by stage, at ~7.5k, 30k and 120k
// vertices, for both Cholesky backends: cotangent weights; the ArapSystem (assembly +
// fill-reducing ordering, once per mesh); the ArapSolver for one constraint set (A_FF
// extracted in the system's order + numeric factorization); the whole ArapSolver(terms,
// ...) constructor (both together); one local/global iteration (and its two halves
// separately); and the solve to convergence with and without Anderson acceleration.
//
// Times: "Time" is wall time of the measured region (manual time where the region is part
// of a loop body); counters *_ms are wall unless named cpu_*; cpu_ms is process CPU time
// of the same region (robust against other processes sharing the cores).
#include <benchmark/benchmark.h>

#include <Eigen/SparseCholesky>
#include <chrono>
#include <map>
#include <memory>
#include <utility>

#include "bench_problems.hpp"

using namespace evar;
using bench::avg;
using bench::bent_tube;
using Clock = std::chrono::steady_clock;

namespace {

double ms_between(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double, std::milli>(b - a).count(); }

// Iteration counts per size so the suite stays short.
int iterations_for(int vertices, int small, int mid, int large) {
  return vertices <= 10000 ? small : vertices <= 40000 ? mid : large;
}

void set_common(benchmark::State& state, const bench::TubeProblem& p) {
  state.counters["vertices"] = static_cast<double>(p.mesh.V.rows());
  state.counters["constrained"] = static_cast<double>(p.constrained.size());
}

// The ArapSystem of a tube problem for a backend, built once (outside any timing).
const std::shared_ptr<const deform::ArapSystem>& tube_system(int vertices, deform::CholeskyBackend backend) {
  static std::map<std::pair<int, int>, std::shared_ptr<const deform::ArapSystem>> cache;
  auto& slot = cache[{vertices, static_cast<int>(backend)}];
  if (!slot) {
    deform::ArapOptions opt;
    opt.backend = backend;
    slot = std::make_shared<const deform::ArapSystem>(bent_tube(vertices).terms, opt);
  }
  return slot;
}

// What ArapSolver factors for a constraint set: the free block A_FF, in the system's
// elimination order restricted to it (for the triangular-solve benchmark).
struct FreeBlock {
  Eigen::SparseMatrix<double> A_FF;
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> ordering;
};
FreeBlock free_block_in_system_order(const deform::ArapSystem& system, const std::vector<int>& constrained) {
  std::vector<int> free_index(static_cast<std::size_t>(system.num_unknowns()), 0);
  for (int c : constrained) free_index[static_cast<std::size_t>(c)] = -1;
  int nf = 0;
  for (auto& f : free_index) f = f < 0 ? -1 : nf++;
  return {bench::free_block(system, constrained), deform::restrict_ordering(system.ordering(), free_index)};
}

// --- cotangent weights (+ building the ARAP terms from them) -------------------------
void BM_TubeWeights(benchmark::State& state, int vertices) {
  const auto& p = bent_tube(vertices);
  double cot = 0, terms = 0, cpu = 0;
  for (auto _ : state) {
    const double c0 = bench::cpu_ms();
    const auto t0 = Clock::now();
    auto edges = deform::cotangent_weights(p.mesh);
    const auto t1 = Clock::now();
    auto arap = deform::mesh_arap_terms(p.mesh.V, edges);
    const auto t2 = Clock::now();
    cpu += bench::cpu_ms() - c0;
    benchmark::DoNotOptimize(arap.weight.data());
    cot += ms_between(t0, t1);
    terms += ms_between(t1, t2);
  }
  set_common(state, p);
  state.counters["cot_ms"] = avg(cot);
  state.counters["terms_ms"] = avg(terms);
  state.counters["cpu_ms"] = avg(cpu);
}

// --- ArapSolver(terms, constrained) constructor: ArapSystem + ArapSolver together ----
void BM_TubeFactor(benchmark::State& state, int vertices, int backend_arg) {
  const auto& p = bent_tube(vertices);
  deform::ArapOptions opt;
  opt.backend = bench::backend_arg(backend_arg);
  if (!bench::backend_usable(state, opt.backend)) return;
  double assemble = 0, ordering = 0, free_block = 0, factor = 0, total = 0, cpu = 0;
  for (auto _ : state) {
    auto terms = p.terms;  // the constructor takes its terms by value: copy outside the timing
    auto constrained = p.constrained;
    const double c0 = bench::cpu_ms();
    const auto t0 = Clock::now();
    const deform::ArapSolver solver(std::move(terms), std::move(constrained), opt);
    const auto t1 = Clock::now();
    cpu += bench::cpu_ms() - c0;
    state.SetIterationTime(ms_between(t0, t1) / 1e3);
    assemble += solver.system().assemble_ms();
    ordering += solver.system().ordering_ms();
    free_block += solver.assemble_ms() - solver.system().assemble_ms();
    factor += solver.factor_ms();
    total += ms_between(t0, t1);
  }
  set_common(state, p);
  state.SetLabel(bench::backend_label(opt.backend));
  state.counters["assemble_ms"] = avg(assemble);  // A (+ tether) assembled
  state.counters["ordering_ms"] = avg(ordering);  // AMD of A's pattern (CHOLMOD orders again itself)
  state.counters["free_block_ms"] = avg(free_block);    // A_FF extracted, its order restricted
  state.counters["factor_ms"] = avg(factor);      // numeric factorization (Eigen: + symbolic, natural order)
  state.counters["ctor_ms"] = avg(total);
  state.counters["cpu_ms"] = avg(cpu);
}

// --- ArapSystem construction alone: assembly + AMD ordering (once per mesh) -----------
void BM_TubeSystem(benchmark::State& state, int vertices) {
  const auto& p = bent_tube(vertices);
  double assemble = 0, ordering = 0, total = 0, cpu = 0;
  for (auto _ : state) {
    auto terms = p.terms;  // copied outside the timing
    const double c0 = bench::cpu_ms();
    const auto t0 = Clock::now();
    const deform::ArapSystem system(std::move(terms));
    const auto t1 = Clock::now();
    cpu += bench::cpu_ms() - c0;
    state.SetIterationTime(ms_between(t0, t1) / 1e3);
    assemble += system.assemble_ms();
    ordering += system.ordering_ms();
    total += ms_between(t0, t1);
    benchmark::DoNotOptimize(system.matrix().valuePtr());
  }
  set_common(state, p);
  state.counters["assemble_ms"] = avg(assemble);
  state.counters["ordering_ms"] = avg(ordering);
  state.counters["system_ms"] = avg(total);
  state.counters["cpu_ms"] = avg(cpu);
  state.counters["nnz_A"] = static_cast<double>(tube_system(vertices, deform::CholeskyBackend::EigenLDLT)->matrix().nonZeros());
}

// --- ArapSolver(system, constrained): free block + numeric factorization, per constraint set
void BM_TubeSolverForConstraints(benchmark::State& state, int vertices, int backend_arg) {
  const auto& p = bent_tube(vertices);
  const auto backend = bench::backend_arg(backend_arg);
  if (!bench::backend_usable(state, backend)) return;
  const auto& system = tube_system(vertices, backend);
  double free_block = 0, factor = 0, total = 0, cpu = 0;
  for (auto _ : state) {
    auto constrained = p.constrained;
    const double c0 = bench::cpu_ms();
    const auto t0 = Clock::now();
    const deform::ArapSolver solver(system, std::move(constrained));
    const auto t1 = Clock::now();
    cpu += bench::cpu_ms() - c0;
    state.SetIterationTime(ms_between(t0, t1) / 1e3);
    free_block += solver.assemble_ms() - system->assemble_ms();
    factor += solver.factor_ms();
    total += ms_between(t0, t1);
  }
  set_common(state, p);
  state.SetLabel(bench::backend_label(backend));
  state.counters["free_block_ms"] = avg(free_block);
  state.counters["factor_ms"] = avg(factor);
  state.counters["solver_ms"] = avg(total);  // + index checks
  state.counters["cpu_ms"] = avg(cpu);
}

// --- for comparison, the bd2df38 path: only the free block A_FF (constrained rows and
// columns removed), ordered by Eigen's own AMD and factored (AMD + symbolic + numeric) ---
void BM_TubeFreeBlockFactor(benchmark::State& state, int vertices) {
  const auto& p = bent_tube(vertices);
  const auto& system = *tube_system(vertices, deform::CholeskyBackend::EigenLDLT);
  bench::time_free_block_factor(state, bench::free_block(system, p.constrained));
  set_common(state, p);
}

// --- the triangular solves of one global step (3 right-hand sides), on the matrix and
// ordering ArapSolver uses (the free block; Eigen: the system's AMD restricted to it)
void BM_TubeTriangularSolve(benchmark::State& state, int vertices, int backend_arg) {
  const auto& p = bent_tube(vertices);
  const auto backend = bench::backend_arg(backend_arg);
  if (!bench::backend_usable(state, backend)) return;
  const auto& system = *tube_system(vertices, backend);
  const auto block = free_block_in_system_order(system, p.constrained);
  const deform::SparseCholesky chol(block.A_FF, block.ordering, backend);
  const geometry::Vertices B = geometry::Vertices::Random(block.A_FF.rows(), 3);
  geometry::Vertices X;
  for (auto _ : state) {
    chol.solve_xyz(B, X);
    benchmark::DoNotOptimize(X.data());
  }
  set_common(state, p);
  state.SetLabel(bench::backend_label(backend));
  state.counters["nnz_A_FF_lower"] = static_cast<double>(block.A_FF.nonZeros());
  if (backend == deform::CholeskyBackend::EigenLDLT) state.counters["nnz_L"] = static_cast<double>(chol.factor_nonzeros());
}

// --- the local step: per-cell covariance + closest rotation, timed through energy() ---
void BM_TubeLocalStep(benchmark::State& state, int vertices) {
  const auto& p = bent_tube(vertices);
  const deform::ArapSolver solver(p.terms, p.constrained);
  const auto X = solver.solve(p.targets).X;  // a bent configuration: rotations up to 60 degrees
  for (auto _ : state) benchmark::DoNotOptimize(solver.energy(X));
  set_common(state, p);
}

// --- one local/global iteration, as iterate_ms / iterations over 20 iterations --------
// (iterate_ms also holds one extra global step before the first iteration: +1/20.)
constexpr int kIterationSample = 20;
void BM_TubeIteration(benchmark::State& state, int vertices, int backend_arg, bool anderson) {
  const auto& p = bent_tube(vertices);
  deform::ArapOptions opt;
  opt.backend = bench::backend_arg(backend_arg);
  opt.anderson = anderson;
  opt.max_iterations = kIterationSample;
  opt.tolerance_mm = 1e-12;  // never reached in 20 iterations: every run does all of them
  if (!bench::backend_usable(state, opt.backend)) return;
  const deform::ArapSolver solver(p.terms, p.constrained, opt);
  double per_iter = 0, init = 0, rejections = 0, cpu = 0, iterations = 0;
  for (auto _ : state) {
    const double c0 = bench::cpu_ms();
    const auto r = solver.solve(p.targets);
    cpu += bench::cpu_ms() - c0;
    const double it = r.iterate_ms / r.iterations;
    state.SetIterationTime(it / 1e3);
    per_iter += it;
    iterations += r.iterations;
    init += r.init_ms;
    rejections += r.anderson_rejections;
  }
  set_common(state, p);
  state.SetLabel(bench::backend_label(opt.backend) + (opt.anderson ? " anderson" : " plain"));
  state.counters["per_iter_ms"] = avg(per_iter);
  // CPU per iteration, init (one global + one local step) included in the division.
  state.counters["cpu_per_iter_ms"] = benchmark::Counter(cpu / iterations);
  state.counters["init_ms"] = avg(init);  // Laplacian editing: one global + one local step
  state.counters["rejections"] = avg(rejections);
}

// --- solve to convergence at the default tolerance (0.01 mm) --------------------------
void BM_TubeSolve(benchmark::State& state, int vertices, int backend_arg, bool anderson) {
  const auto& p = bent_tube(vertices);
  deform::ArapOptions opt;  // defaults: tolerance 0.01 mm, max 500 iterations
  opt.backend = bench::backend_arg(backend_arg);
  opt.anderson = anderson;
  if (!bench::backend_usable(state, opt.backend)) return;
  const deform::ArapSolver solver(p.terms, p.constrained, opt);
  double iterations = 0, iterate = 0, init = 0, rejections = 0, converged = 0, last = 0, cpu = 0;
  for (auto _ : state) {
    const double c0 = bench::cpu_ms();
    const auto r = solver.solve(p.targets);
    cpu += bench::cpu_ms() - c0;
    state.SetIterationTime((r.init_ms + r.iterate_ms) / 1e3);
    iterations += r.iterations;
    iterate += r.iterate_ms;
    init += r.init_ms;
    rejections += r.anderson_rejections;
    converged += r.converged ? 1 : 0;
    last += r.last_update_mm;
  }
  set_common(state, p);
  state.SetLabel(bench::backend_label(opt.backend) + (opt.anderson ? " anderson" : " plain"));
  state.counters["arap_iterations"] = avg(iterations);
  state.counters["iterate_ms"] = avg(iterate);
  state.counters["init_ms"] = avg(init);
  state.counters["per_iter_ms"] = benchmark::Counter(iterations > 0 ? iterate / iterations : 0.0);
  state.counters["cpu_ms"] = avg(cpu);  // init + iterations
  state.counters["rejections"] = avg(rejections);
  state.counters["converged"] = avg(converged);
  state.counters["last_update_mm"] = avg(last);
  state.counters["assemble_ms"] = solver.assemble_ms();  // of the one solver used
  state.counters["factor_ms"] = solver.factor_ms();
}

// Registration: names are tube_<stage>/<vertices>[/<backend>[/<anderson|plain>]]. Each
// size gets its own iteration count so the suite stays short.
struct Registrar {
  template <class Fn, class... Args>
  static void add(const std::string& name, int iterations, bool manual_time, Fn fn, Args... args) {
    bench::register_fixed(name, iterations, manual_time, fn, args...);
  }
  Registrar() {
    const char* backends[] = {"eigen", "cholmod"};
    for (int v : bench::kSizes) {
      const std::string s = std::to_string(v);
      add("tube_weights/" + s, iterations_for(v, 40, 10, 3), false, BM_TubeWeights, v);
      add("tube_local_step/" + s, iterations_for(v, 40, 10, 3), false, BM_TubeLocalStep, v);
      add("tube_system/" + s, iterations_for(v, 20, 5, 2), true, BM_TubeSystem, v);
      add("tube_free_block_factor/" + s, iterations_for(v, 20, 5, 2), false, BM_TubeFreeBlockFactor, v);
      for (int b = 0; b < 2; ++b) {
        const std::string sb = s + "/" + backends[b];
        add("tube_factor/" + sb, iterations_for(v, 20, 5, 2), true, BM_TubeFactor, v, b);
        add("tube_constraint_set/" + sb, iterations_for(v, 20, 5, 2), true, BM_TubeSolverForConstraints, v, b);
        add("tube_triangular_solve/" + sb, iterations_for(v, 100, 30, 10), false, BM_TubeTriangularSolve, v, b);
        for (bool a : {true, false}) {
          const std::string sba = sb + (a ? "/anderson" : "/plain");
          add("tube_iteration/" + sba, iterations_for(v, 5, 2, 1), true, BM_TubeIteration, v, b, a);
          add("tube_solve/" + sba, iterations_for(v, 2, 1, 1), true, BM_TubeSolve, v, b, a);
        }
      }
    }
  }
};
const Registrar registrar;

}  // namespace
