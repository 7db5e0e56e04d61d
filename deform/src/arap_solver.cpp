#include "evar/deform/arap_solver.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <numeric>
#include <stdexcept>
#include <string>

#include "evar/deform/closest_rotation.hpp"

namespace evar::deform {
namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// Union-find over unknowns to check that every component is pinned down.
struct DisjointSets {
  std::vector<int> parent;
  explicit DisjointSets(int n) : parent(static_cast<std::size_t>(n)) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int x) {
    while (parent[static_cast<std::size_t>(x)] != x) x = parent[static_cast<std::size_t>(x)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(x)])];
    return x;
  }
  void unite(int a, int b) { parent[static_cast<std::size_t>(find(a))] = find(b); }
};

void check_components(const ArapTerms& terms, const std::vector<int>& constrained) {
  DisjointSets sets(terms.num_unknowns);
  for (int t = 0; t < terms.num_terms(); ++t)
    for (int p = terms.coeff_begin[static_cast<std::size_t>(t)] + 1; p < terms.coeff_begin[static_cast<std::size_t>(t) + 1]; ++p)
      sets.unite(terms.coeff_index[static_cast<std::size_t>(p) - 1], terms.coeff_index[static_cast<std::size_t>(p)]);
  std::vector<char> pinned(static_cast<std::size_t>(terms.num_unknowns), 0);
  for (int c : constrained) pinned[static_cast<std::size_t>(sets.find(c))] = 1;
  for (int k = 0; k < terms.num_unknowns; ++k)
    if (!pinned[static_cast<std::size_t>(sets.find(k))])
      throw std::invalid_argument("the connected part containing vertex " + std::to_string(k) +
                                  " has no fixed or handle vertex, so its position is undetermined");
}

}  // namespace

ArapSolver::ArapSolver(ArapTerms terms, std::vector<int> constrained, ArapOptions options, ArapTether tether)
    : terms_(std::move(terms)), constrained_(std::move(constrained)), options_(options), tether_(std::move(tether)) {
  const int n = terms_.num_unknowns;
  const bool tethered = !tether_.weight.empty();
  if (tethered && (tether_.weight.size() != static_cast<std::size_t>(n) || tether_.anchor.rows() != n))
    throw std::invalid_argument("ARAP tether: one weight and one anchor per unknown are required");
  if (constrained_.empty() && !tethered) throw std::invalid_argument("ARAP needs at least one fixed or handle vertex");
  if (options_.max_iterations < 0 || !(options_.tolerance_mm > 0.0) || options_.anderson_window < 1)
    throw std::invalid_argument("ARAP options: iterations >= 0, tolerance > 0 and Anderson window >= 1 are required");
  free_row_.assign(static_cast<std::size_t>(n), -1);
  std::vector<int> constrained_row(static_cast<std::size_t>(n), -1);
  for (std::size_t c = 0; c < constrained_.size(); ++c) {
    const int k = constrained_[c];
    if (k < 0 || k >= n) throw std::invalid_argument("constrained index " + std::to_string(k) + " is out of range");
    if (constrained_row[static_cast<std::size_t>(k)] >= 0)
      throw std::invalid_argument("vertex " + std::to_string(k) + " is constrained twice");
    constrained_row[static_cast<std::size_t>(k)] = static_cast<int>(c);
  }
  for (int k = 0; k < n; ++k)
    if (constrained_row[static_cast<std::size_t>(k)] < 0) {
      free_row_[static_cast<std::size_t>(k)] = static_cast<int>(free_.size());
      free_.push_back(k);
    }
  if (!tethered) check_components(terms_, constrained_);

  const auto t0 = Clock::now();
  for (int t = 0; t < terms_.num_terms(); ++t)
    rest_energy_ += terms_.weight[static_cast<std::size_t>(t)] * terms_.rest[static_cast<std::size_t>(t)].squaredNorm();
  Eigen::SparseMatrix<double> A = assemble_system_matrix(terms_);
  if (tethered) {
    Eigen::SparseMatrix<double> T(n, n);
    std::vector<Eigen::Triplet<double>> diag;
    for (int k = 0; k < n; ++k)
      if (tether_.weight[static_cast<std::size_t>(k)] > 0.0) diag.emplace_back(k, k, tether_.weight[static_cast<std::size_t>(k)]);
    T.setFromTriplets(diag.begin(), diag.end());
    A += T;
  }
  // Split A into the free block and the free-constrained coupling.
  std::vector<Eigen::Triplet<double>> ff, fc;
  ff.reserve(static_cast<std::size_t>(A.nonZeros()));
  for (int col = 0; col < A.outerSize(); ++col)
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, col); it; ++it) {
      const int r = free_row_[static_cast<std::size_t>(it.row())];
      if (r < 0) continue;
      const int fcol = free_row_[static_cast<std::size_t>(col)];
      if (fcol >= 0) {
        if (r >= fcol) ff.emplace_back(r, fcol, it.value());  // lower triangle suffices
      } else {
        fc.emplace_back(r, constrained_row[static_cast<std::size_t>(col)], it.value());
      }
    }
  const auto nf = static_cast<Eigen::Index>(free_.size());
  Eigen::SparseMatrix<double> A_FF(nf, nf);
  A_FF.setFromTriplets(ff.begin(), ff.end());
  A_FC_.resize(nf, static_cast<Eigen::Index>(constrained_.size()));
  A_FC_.setFromTriplets(fc.begin(), fc.end());
  tether_rhs_ = Eigen::MatrixXd::Zero(nf, 3);
  if (tethered)
    for (Eigen::Index r = 0; r < nf; ++r) {
      const auto k = static_cast<std::size_t>(free_[static_cast<std::size_t>(r)]);
      tether_rhs_.row(r) = tether_.weight[k] * tether_.anchor.row(static_cast<Eigen::Index>(k));
    }
  assemble_ms_ = ms_since(t0);

  const auto t1 = Clock::now();
  if (nf > 0) cholesky_.emplace(A_FF, options_.backend);
  factor_ms_ = ms_since(t1);
}

double ArapSolver::local_step(const Positions& X, std::vector<Eigen::Matrix3d>& R) const {
  double E = rest_energy_;
  const auto* idx = terms_.coeff_index.data();
  const auto* val = terms_.coeff_value.data();
  for (int c = 0; c < terms_.num_cells; ++c) {
    Eigen::Matrix3d S = Eigen::Matrix3d::Zero();  // Σ w e' eᵀ
    double deformed_sq = 0.0;
    for (int t = terms_.cell_begin[static_cast<std::size_t>(c)]; t < terms_.cell_begin[static_cast<std::size_t>(c) + 1]; ++t) {
      Eigen::Vector3d ep = Eigen::Vector3d::Zero();
      for (int p = terms_.coeff_begin[static_cast<std::size_t>(t)]; p < terms_.coeff_begin[static_cast<std::size_t>(t) + 1]; ++p)
        ep += val[p] * X.row(idx[p]).transpose();
      const double w = terms_.weight[static_cast<std::size_t>(t)];
      S.noalias() += (w * ep) * terms_.rest[static_cast<std::size_t>(t)].transpose();
      deformed_sq += w * ep.squaredNorm();
    }
    auto& Rc = R[static_cast<std::size_t>(c)];
    Rc = closest_rotation(S, Rc);
    E += deformed_sq - 2.0 * Rc.cwiseProduct(S).sum();  // Σ w |e' − R e|²
  }
  if (!tether_.weight.empty())
    for (int k = 0; k < terms_.num_unknowns; ++k)
      E += tether_.weight[static_cast<std::size_t>(k)] * (X.row(k) - tether_.anchor.row(k)).squaredNorm();
  return std::max(E, 0.0);
}

Eigen::MatrixXd ArapSolver::global_step(const std::vector<Eigen::Matrix3d>& R, const Eigen::MatrixXd& fixed_rhs) const {
  Positions b = Positions::Zero(static_cast<Eigen::Index>(free_.size()), 3);
  const auto* idx = terms_.coeff_index.data();
  const auto* val = terms_.coeff_value.data();
  for (int c = 0; c < terms_.num_cells; ++c) {
    const Eigen::Matrix3d& Rc = R[static_cast<std::size_t>(c)];
    for (int t = terms_.cell_begin[static_cast<std::size_t>(c)]; t < terms_.cell_begin[static_cast<std::size_t>(c) + 1]; ++t) {
      const Eigen::Vector3d r = terms_.weight[static_cast<std::size_t>(t)] * (Rc * terms_.rest[static_cast<std::size_t>(t)]);
      for (int p = terms_.coeff_begin[static_cast<std::size_t>(t)]; p < terms_.coeff_begin[static_cast<std::size_t>(t) + 1]; ++p) {
        const int row = free_row_[static_cast<std::size_t>(idx[p])];
        if (row >= 0) b.row(row) += val[p] * r.transpose();
      }
    }
  }
  Eigen::MatrixXd rhs = b;
  rhs -= fixed_rhs;
  rhs += tether_rhs_;
  return cholesky_->solve(rhs);
}

double ArapSolver::energy(const Positions& X) const {
  std::vector<Eigen::Matrix3d> R(static_cast<std::size_t>(terms_.num_cells), Eigen::Matrix3d::Identity());
  return local_step(X, R);
}

ArapResult ArapSolver::solve(const Positions& targets, const Positions* initial) const {
  const int n = terms_.num_unknowns;
  if (targets.rows() != static_cast<Eigen::Index>(constrained_.size()))
    throw std::invalid_argument("ARAP solve: " + std::to_string(targets.rows()) + " targets for " +
                                std::to_string(constrained_.size()) + " constrained vertices");
  if (!targets.allFinite()) throw std::invalid_argument("ARAP solve: a target position is not finite");
  if (initial && (initial->rows() != n || !initial->allFinite()))
    throw std::invalid_argument("ARAP solve: the initial guess must have one finite row per unknown");

  ArapResult result;
  const auto t_init = Clock::now();
  Positions& X = result.X;
  X = initial ? *initial : Positions::Zero(n, 3);
  Eigen::MatrixXd X_C(static_cast<Eigen::Index>(constrained_.size()), 3);
  for (std::size_t c = 0; c < constrained_.size(); ++c) {
    X.row(constrained_[c]) = targets.row(static_cast<Eigen::Index>(c));
    X_C.row(static_cast<Eigen::Index>(c)) = targets.row(static_cast<Eigen::Index>(c));
  }
  const auto nf = static_cast<Eigen::Index>(free_.size());
  auto scatter = [&](const Eigen::MatrixXd& xf) {
    for (Eigen::Index r = 0; r < nf; ++r) X.row(free_[static_cast<std::size_t>(r)]) = xf.row(r);
  };
  std::vector<Eigen::Matrix3d> R(static_cast<std::size_t>(terms_.num_cells), Eigen::Matrix3d::Identity());
  if (nf == 0) {
    result.energy.push_back(local_step(X, R));
    result.converged = true;
    result.init_ms = ms_since(t_init);
    return result;
  }
  const Eigen::MatrixXd fixed_rhs = constrained_.empty() ? Eigen::MatrixXd::Zero(nf, 3) : Eigen::MatrixXd(A_FC_ * X_C);
  Eigen::MatrixXd x(nf, 3);
  if (initial) {
    for (Eigen::Index r = 0; r < nf; ++r) x.row(r) = X.row(free_[static_cast<std::size_t>(r)]);
  } else {
    x = global_step(R, fixed_rhs);  // Laplacian editing: all rotations identity
    scatter(x);
  }
  double E = local_step(X, R);
  result.energy.push_back(E);
  result.init_ms = ms_since(t_init);

  const auto t_iter = Clock::now();
  // Anderson history: differences of successive g = G(x) and f = G(x) − x (flattened).
  const int m = options_.anderson_window;
  const Eigen::Index N = nf * 3;
  Eigen::MatrixXd dG(N, m), dF(N, m);
  Eigen::VectorXd prev_g(N), prev_f(N);
  int history = 0, next_col = 0;
  bool have_prev = false;

  Eigen::MatrixXd g = global_step(R, fixed_rhs);
  for (int it = 1; it <= options_.max_iterations; ++it) {
    const Eigen::MatrixXd f = g - x;
    result.last_update_mm = f.rowwise().norm().maxCoeff();
    result.iterations = it;
    if (result.last_update_mm < options_.tolerance_mm) {
      x = g;
      scatter(x);
      E = local_step(X, R);
      result.energy.push_back(E);
      result.converged = true;
      break;
    }
    Eigen::MatrixXd candidate = g;
    bool accelerated = false;
    if (options_.anderson) {
      const Eigen::Map<const Eigen::VectorXd> gv(g.data(), N), fv(f.data(), N);
      if (have_prev) {
        dG.col(next_col) = gv - prev_g;
        dF.col(next_col) = fv - prev_f;
        next_col = (next_col + 1) % m;
        history = std::min(history + 1, m);
      }
      prev_g = gv;
      prev_f = fv;
      have_prev = true;
      if (history > 0) {
        // θ = argmin |f − ΔF θ|, via regularized normal equations on column-scaled ΔF.
        const auto dFh = dF.leftCols(history);
        Eigen::VectorXd scale = dFh.colwise().norm().transpose();
        for (int j = 0; j < history; ++j) scale(j) = scale(j) > 0.0 ? 1.0 / scale(j) : 0.0;
        Eigen::MatrixXd M = scale.asDiagonal() * (dFh.transpose() * dFh) * scale.asDiagonal();
        M.diagonal().array() += 1e-10;
        const Eigen::VectorXd theta = scale.asDiagonal() * M.ldlt().solve(scale.asDiagonal() * (dFh.transpose() * fv));
        if (theta.allFinite()) {
          Eigen::VectorXd xv = gv - dG.leftCols(history) * theta;
          candidate = Eigen::Map<Eigen::MatrixXd>(xv.data(), nf, 3);
          accelerated = true;
        }
      }
    }
    scatter(candidate);
    std::vector<Eigen::Matrix3d> R_candidate = R;
    double E_candidate = local_step(X, R_candidate);
    if (accelerated && !(E_candidate < E)) {
      // Safeguard: fall back to the plain local/global step, which cannot raise E.
      ++result.anderson_rejections;
      candidate = g;
      scatter(candidate);
      R_candidate = R;
      E_candidate = local_step(X, R_candidate);
      history = 0;
      next_col = 0;
      have_prev = false;
    }
    x = std::move(candidate);
    R = std::move(R_candidate);
    E = E_candidate;
    result.energy.push_back(E);
    g = global_step(R, fixed_rhs);
  }
  if (!result.converged) {
    scatter(g);  // the last global solve is the best estimate we have
    result.energy.push_back(local_step(X, R));
  }
  result.iterate_ms = ms_since(t_iter);
  return result;
}

ArapTerms mesh_arap_terms(const Positions& V, const std::vector<WeightedEdge>& edges) {
  return surface_arap_terms(V, edges, static_cast<int>(V.rows()));
}

}  // namespace evar::deform
