// ARAP on a bent tube (surface ARAP, no skeleton), stage by stage, at ~7.5k, 30k and 120k
// vertices, for both Cholesky backends: cotangent weights, assembly + factorization, one
// local/global iteration (and its two halves separately), and the solve to convergence
// with and without Anderson acceleration.
//
// Times: "Time" is wall time of the measured region (manual time where the region is part
// of a loop body); counters *_ms are wall unless named cpu_*; cpu_ms is process CPU time
// of the same region (robust against other processes sharing the cores).
#include <benchmark/benchmark.h>

#include <Eigen/SparseCholesky>
#include <chrono>

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

// A_FF (lower triangle) as ArapSolver builds it, for the triangular-solve benchmark.
Eigen::SparseMatrix<double> free_block(const bench::TubeProblem& p) {
  const Eigen::SparseMatrix<double> A = deform::assemble_system_matrix(p.terms);
  std::vector<int> row(static_cast<std::size_t>(A.rows()), 0);
  for (int c : p.constrained) row[static_cast<std::size_t>(c)] = -1;
  int nf = 0;
  for (auto& r : row) r = r < 0 ? -1 : nf++;
  std::vector<Eigen::Triplet<double>> t;
  for (int col = 0; col < A.outerSize(); ++col)
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, col); it; ++it) {
      const int r = row[static_cast<std::size_t>(it.row())], c = row[static_cast<std::size_t>(col)];
      if (r >= 0 && c >= 0 && r >= c) t.emplace_back(r, c, it.value());
    }
  Eigen::SparseMatrix<double> F(nf, nf);
  F.setFromTriplets(t.begin(), t.end());
  return F;
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

// --- ArapSolver constructor: assembly + factorization ---------------------------------
void BM_TubeFactor(benchmark::State& state, int vertices, int backend_arg) {
  const auto& p = bent_tube(vertices);
  deform::ArapOptions opt;
  opt.backend = bench::backend_arg(backend_arg);
  if (!bench::backend_usable(state, opt.backend)) return;
  double assemble = 0, factor = 0, total = 0, cpu = 0;
  for (auto _ : state) {
    auto terms = p.terms;  // the constructor takes its terms by value: copy outside the timing
    auto constrained = p.constrained;
    const double c0 = bench::cpu_ms();
    const auto t0 = Clock::now();
    const deform::ArapSolver solver(std::move(terms), std::move(constrained), opt);
    const auto t1 = Clock::now();
    cpu += bench::cpu_ms() - c0;
    state.SetIterationTime(ms_between(t0, t1) / 1e3);
    assemble += solver.assemble_ms();
    factor += solver.factor_ms();
    total += ms_between(t0, t1);
  }
  set_common(state, p);
  state.SetLabel(bench::backend_label(opt.backend));
  state.counters["assemble_ms"] = avg(assemble);
  state.counters["factor_ms"] = avg(factor);
  state.counters["ctor_ms"] = avg(total);  // + component check and free/constrained split
  state.counters["cpu_ms"] = avg(cpu);
}

// --- the triangular solves of one global step (3 right-hand sides) --------------------
void BM_TubeTriangularSolve(benchmark::State& state, int vertices, int backend_arg) {
  const auto& p = bent_tube(vertices);
  const auto backend = bench::backend_arg(backend_arg);
  if (!bench::backend_usable(state, backend)) return;
  const Eigen::SparseMatrix<double> A_FF = free_block(p);
  const deform::SparseCholesky chol(A_FF, backend);
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(A_FF.rows(), 3);
  for (auto _ : state) {
    Eigen::MatrixXd X = chol.solve(B);
    benchmark::DoNotOptimize(X.data());
  }
  set_common(state, p);
  state.SetLabel(bench::backend_label(backend));
  state.counters["nnz_A_FF_lower"] = static_cast<double>(A_FF.nonZeros());
  if (backend == deform::CholeskyBackend::EigenLDLT) {
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::AMDOrdering<int>> ldlt(A_FF);
    state.counters["nnz_L"] = static_cast<double>(ldlt.matrixL().nestedExpression().nonZeros());
  }
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
    auto* b = benchmark::RegisterBenchmark(name.c_str(), fn, args...);
    b->Iterations(iterations)->Unit(benchmark::kMillisecond);
    if (manual_time) b->UseManualTime();
  }
  Registrar() {
    const char* backends[] = {"eigen", "cholmod"};
    for (int v : bench::kSizes) {
      const std::string s = std::to_string(v);
      add("tube_weights/" + s, iterations_for(v, 40, 10, 3), false, BM_TubeWeights, v);
      add("tube_local_step/" + s, iterations_for(v, 40, 10, 3), false, BM_TubeLocalStep, v);
      for (int b = 0; b < 2; ++b) {
        const std::string sb = s + "/" + backends[b];
        add("tube_factor/" + sb, iterations_for(v, 20, 5, 2), true, BM_TubeFactor, v, b);
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
