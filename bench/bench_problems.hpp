#pragma once
// Shared problems for the benchmarks: a bent tube (surface ARAP) and the example
// aorto-iliac scene converted in memory to a geometry::Scene. Built once per size and
// cached, so set-up never counts in a benchmark's time.
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <cmath>
#include <ctime>
#include <map>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include "evar/deform/arap_solver.hpp"
#include "evar/deform/cotangent_weights.hpp"
#include "evar/deform/sparse_cholesky.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/sim/example_scene.hpp"
#include "evar/sim/tube_mesh.hpp"

namespace evar::bench {

/// Tube sizes (target vertex counts) shared by the benchmarks.
inline constexpr int kSizes[] = {7500, 30000, 120000};

/// Benchmark argument -> Cholesky backend (0: Eigen SimplicialLDLT, 1: CHOLMOD supernodal).
inline deform::CholeskyBackend backend_arg(std::int64_t a) {
  return a == 0 ? deform::CholeskyBackend::EigenLDLT : deform::CholeskyBackend::Cholmod;
}

/// Returns false (and marks the run skipped) when the backend is not in this build.
inline bool backend_usable(benchmark::State& state, deform::CholeskyBackend b) {
  if (b == deform::CholeskyBackend::Cholmod && !deform::cholmod_available()) {
    state.SkipWithError("this build has no CHOLMOD");
    return false;
  }
  return true;
}

inline std::string backend_label(deform::CholeskyBackend b) { return deform::to_string(b); }

/// A straight capped tube (length 120 mm, radius 10 mm, along +z) bent by its ends: the
/// vertices of the bottom 3 mm are fixed where they are; those of the top 3 mm are moved
/// rigidly to where a 60 degree circular bend of the axis would put them (the top is turned
/// 60 degrees about x and its centre moved by about 57 mm sideways and 21 mm down). The
/// middle is free. Every other vertex starts from Laplacian editing in the solver.
struct TubeProblem {
  geometry::TriangleMesh mesh;
  std::vector<int> constrained;  ///< fixed bottom, then moved top (mesh order)
  geometry::Vertices targets;     ///< one row per constrained vertex
  deform::ArapTerms terms;       ///< surface ARAP terms with cotangent weights
};

inline TubeProblem make_bent_tube(int target_vertices) {
  constexpr double kLength = 120.0, kRadius = 10.0, kEndBand = 3.0;
  const double theta = 60.0 * std::numbers::pi / 180.0;
  const std::vector<Eigen::Vector3d> centerline{{0, 0, 0}, {0, 0, kLength}};
  const auto options = sim::tube_options_for_vertex_count(kLength, kRadius, target_vertices);
  TubeProblem p;
  p.mesh = sim::tube_mesh(centerline, [](double) { return kRadius; }, options);
  const double rho = kLength / theta;  // bend radius of the axis
  const Eigen::Vector3d top_centre(0, 0, kLength);
  const Eigen::Vector3d bent_top(0, rho * (1.0 - std::cos(theta)), rho * std::sin(theta));
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(-theta, Eigen::Vector3d::UnitX()).toRotationMatrix();  // +z -> (0, sin, cos)
  std::vector<Eigen::Vector3d> rows;
  for (Eigen::Index i = 0; i < p.mesh.V.rows(); ++i) {
    const Eigen::Vector3d v = p.mesh.V.row(i).transpose();
    if (v.z() < kEndBand) {
      p.constrained.push_back(static_cast<int>(i));
      rows.push_back(v);
    } else if (v.z() > kLength - kEndBand) {
      p.constrained.push_back(static_cast<int>(i));
      rows.push_back(Q * (v - top_centre) + bent_top);
    }
  }
  p.targets.resize(static_cast<Eigen::Index>(rows.size()), 3);
  for (std::size_t k = 0; k < rows.size(); ++k) p.targets.row(static_cast<Eigen::Index>(k)) = rows[k].transpose();
  p.terms = deform::mesh_arap_terms(p.mesh.V, deform::cotangent_weights(p.mesh));
  return p;
}

/// Cached per target vertex count.
inline const TubeProblem& bent_tube(int target_vertices) {
  static std::map<int, std::unique_ptr<TubeProblem>> cache;
  auto& slot = cache[target_vertices];
  if (!slot) slot = std::make_unique<TubeProblem>(make_bent_tube(target_vertices));
  return *slot;
}

/// Example scene parameters with the aorta at `aorta_vertices` and the iliacs scaled in
/// proportion (the default scene is 7500 aorta + 2 x 3500 iliac vertices).
inline sim::ExampleSceneParams scene_params(int aorta_vertices) {
  sim::ExampleSceneParams p;
  const double scale = static_cast<double>(aorta_vertices) / p.aorta_vertices;
  p.iliac_vertices = static_cast<int>(std::lround(p.iliac_vertices * scale));
  p.aorta_vertices = aorta_vertices;
  return p;
}

struct SceneProblem {
  sim::ExampleScene example;
  geometry::Scene scene;
};

inline const SceneProblem& example_scene(int aorta_vertices) {
  static std::map<int, std::unique_ptr<SceneProblem>> cache;
  auto& slot = cache[aorta_vertices];
  if (!slot) {
    slot = std::make_unique<SceneProblem>();
    slot->example = sim::make_example_scene(scene_params(aorta_vertices));
    slot->scene = sim::to_scene(slot->example);
  }
  return *slot;
}

/// Largest distance (mm) between corresponding rows.
inline double max_row_distance(const geometry::Vertices& a, const geometry::Vertices& b) {
  return (a - b).rowwise().norm().maxCoeff();
}

/// A counter averaged over the benchmark's iterations.
inline benchmark::Counter avg(double sum) { return benchmark::Counter(sum, benchmark::Counter::kAvgIterations); }

/// Registers benchmark `name` running `fn(state, args...)` for a fixed number of iterations,
/// in milliseconds; `manual_time`: the benchmark sets each iteration's time itself.
template <class Fn, class... Args>
void register_fixed(const std::string& name, int iterations, bool manual_time, Fn fn, Args... args) {
  auto* b = benchmark::RegisterBenchmark(name.c_str(), fn, args...);
  b->Iterations(iterations)->Unit(benchmark::kMillisecond);
  if (manual_time) b->UseManualTime();
}

/// Process CPU time (ms), all threads: single-threaded work measured this way is not
/// inflated when other processes compete for the cores (wall time is).
inline double cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

/// The free block A_FF of a system (lower triangle) for a constraint set: what the solver
/// factored before the shared ArapSystem (commit bd2df38), kept for comparison.
inline Eigen::SparseMatrix<double> free_block(const deform::ArapSystem& system, const std::vector<int>& constrained) {
  const auto& A = system.matrix();
  std::vector<int> row(static_cast<std::size_t>(A.rows()), 0);
  for (int c : constrained) row[static_cast<std::size_t>(c)] = -1;
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

/// Times factoring A_FF with its own AMD ordering (Eigen LDLT) over `state`'s iterations;
/// sets the label and the cpu_ms and nnz_L counters.
inline void time_free_block_factor(benchmark::State& state, const Eigen::SparseMatrix<double>& A_FF) {
  double cpu = 0;
  for (auto _ : state) {
    const double c0 = cpu_ms();
    const deform::SparseCholesky chol(A_FF, deform::CholeskyBackend::EigenLDLT);
    cpu += cpu_ms() - c0;
    benchmark::DoNotOptimize(&chol);
  }
  state.SetLabel("eigen, A_FF with its own AMD (bd2df38)");
  state.counters["cpu_ms"] = state.iterations() > 0 ? cpu / static_cast<double>(state.iterations()) : 0.0;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::AMDOrdering<int>> ldlt(A_FF);
  state.counters["nnz_L"] = static_cast<double>(ldlt.matrixL().nestedExpression().nonZeros());
}

}  // namespace evar::bench
