#include "evar/deform/arap_solver.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <array>
#include <chrono>
#include <numeric>
#include <stdexcept>
#include <string>

#include "anderson_mixing.hpp"
#include "evar/base/elapsed.hpp"
#include "closest_rotation.hpp"

namespace evar::deform {
namespace {

using Clock = std::chrono::steady_clock;
using base::ms_since;

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

ArapSystem::ArapSystem(ArapTerms terms, ArapOptions options, ArapTether tether, const ArapKnots& knots)
    : terms_(std::move(terms)), options_(options), tether_(std::move(tether)) {
  const int n = terms_.num_unknowns;
  if (options_.max_iterations < 0 || !(options_.tolerance_mm > 0.0) || options_.anderson_window < 1)
    throw std::invalid_argument("ARAP options: iterations >= 0, tolerance > 0 and Anderson window >= 1 are required");
  if (!tether_.weight.empty() && (tether_.weight.size() != static_cast<std::size_t>(n) || tether_.anchor.rows() != n))
    throw std::invalid_argument("ARAP tether: one weight and one anchor per unknown are required");
  const auto t0 = Clock::now();
  for (int t = 0; t < terms_.num_terms(); ++t)
    rest_energy_ += terms_.weight[static_cast<std::size_t>(t)] * terms_.rest[static_cast<std::size_t>(t)].squaredNorm();
  A_ = assemble_system_matrix(terms_);
  if (!tether_.weight.empty()) {
    std::vector<Eigen::Triplet<double>> diag;
    for (int k = 0; k < n; ++k)
      if (tether_.weight[static_cast<std::size_t>(k)] > 0.0) diag.emplace_back(k, k, tether_.weight[static_cast<std::size_t>(k)]);
    Eigen::SparseMatrix<double> T(n, n);
    T.setFromTriplets(diag.begin(), diag.end());
    A_ += T;
  }
  // Every diagonal entry stored, so every free block A_FF has its whole diagonal.
  {
    Eigen::SparseMatrix<double> I(n, n);
    I.setIdentity();
    A_ += 0.0 * I;
  }
  A_.makeCompressed();
  for (int c = 0; c < terms_.num_cells; ++c) {
    const auto first = cell_unknown_.size();
    for (int t = terms_.cell_begin[static_cast<std::size_t>(c)]; t < terms_.cell_begin[static_cast<std::size_t>(c) + 1]; ++t)
      for (int p = terms_.coeff_begin[static_cast<std::size_t>(t)]; p < terms_.coeff_begin[static_cast<std::size_t>(t) + 1]; ++p) {
        const int k = terms_.coeff_index[static_cast<std::size_t>(p)];
        const Eigen::Vector3d m =
            terms_.weight[static_cast<std::size_t>(t)] * terms_.coeff_value[static_cast<std::size_t>(p)] * terms_.rest[static_cast<std::size_t>(t)];
        const auto at = std::find(cell_unknown_.begin() + static_cast<std::ptrdiff_t>(first), cell_unknown_.end(), k);
        if (at == cell_unknown_.end()) {
          cell_unknown_.push_back(k);
          cell_moment_.push_back(m);
        } else {
          cell_moment_[static_cast<std::size_t>(at - cell_unknown_.begin())] += m;
        }
      }
    cell_unknown_begin_.push_back(static_cast<int>(cell_unknown_.size()));
  }
  tether_rhs_ = geometry::Vertices::Zero(n, 3);
  if (!tether_.weight.empty())
    for (int k = 0; k < n; ++k) tether_rhs_.row(k) = tether_.weight[static_cast<std::size_t>(k)] * tether_.anchor.row(k);
  if (!knots.arc_of_unknown.empty()) coarse_.emplace(terms_, tether_.weight, knots);
  assemble_ms_ = ms_since(t0);
  const auto t1 = Clock::now();
  if (n > 0) ordering_ = fill_reducing_ordering(A_);
  ordering_ms_ = ms_since(t1);
}

const SparseCholesky* ArapSystem::prefactored() const {
  std::call_once(prefactor_once_, [this] {
    if (tether_.weight.empty() || num_unknowns() == 0) return;
    try {
      prefactored_.emplace(A_, ordering_, options_.backend);
    } catch (const std::runtime_error&) {
      // Singular without constraints: every constraint set is factored on its own.
    }
  });
  return prefactored_ ? &*prefactored_ : nullptr;
}

double ArapSystem::local_step(const geometry::Vertices& X, std::vector<Eigen::Matrix3d>& R) const {
  return local_step(X, R, R, nullptr);
}

double ArapSystem::local_step(const geometry::Vertices& X, const std::vector<Eigen::Matrix3d>& R_warm,
                              std::vector<Eigen::Matrix3d>& R, geometry::Vertices* b) const {
  R.resize(R_warm.size());
  if (b) *b = tether_rhs_;
  double E = rest_energy_;
  const auto* idx = terms_.coeff_index.data();
  const auto* val = terms_.coeff_value.data();
  // Cells in blocks: covariances, then rotations (eight at a time in vector registers,
  // refine_rotations), then energy and b(R) while the block is in cache.
  constexpr int kBlock = 32;
  std::array<Eigen::Matrix3d, kBlock> S_block;
  std::array<double, kBlock> sq_block;
  for (int c0 = 0; c0 < terms_.num_cells; c0 += kBlock) {
    const int c1 = std::min(c0 + kBlock, terms_.num_cells);
    for (int c = c0; c < c1; ++c) {
      const auto cu = static_cast<std::size_t>(c);
      Eigen::Matrix3d S = Eigen::Matrix3d::Zero();  // Σ w e' eᵀ
      double deformed_sq = 0.0;
      for (int t = terms_.cell_begin[cu]; t < terms_.cell_begin[cu + 1]; ++t) {
        Eigen::Vector3d ep = Eigen::Vector3d::Zero();
        for (int p = terms_.coeff_begin[static_cast<std::size_t>(t)]; p < terms_.coeff_begin[static_cast<std::size_t>(t) + 1]; ++p)
          ep += val[p] * X.row(idx[p]).transpose();
        const double w = terms_.weight[static_cast<std::size_t>(t)];
        S.noalias() += (w * ep) * terms_.rest[static_cast<std::size_t>(t)].transpose();
        deformed_sq += w * ep.squaredNorm();
      }
      S_block[static_cast<std::size_t>(c - c0)] = S;
      sq_block[static_cast<std::size_t>(c - c0)] = deformed_sq;
    }
    refine_rotations(S_block.data(), R_warm.data() + c0, R.data() + c0, c1 - c0);
    for (int c = c0; c < c1; ++c) {
      const auto cu = static_cast<std::size_t>(c);
      const Eigen::Matrix3d& Rc = R[cu];
      E += sq_block[static_cast<std::size_t>(c - c0)] - 2.0 * Rc.cwiseProduct(S_block[static_cast<std::size_t>(c - c0)]).sum();  // Σ w |e' − R e|²
      if (b)
        for (int q = cell_unknown_begin_[cu]; q < cell_unknown_begin_[cu + 1]; ++q)
          b->row(cell_unknown_[static_cast<std::size_t>(q)]).noalias() += (Rc * cell_moment_[static_cast<std::size_t>(q)]).transpose();
    }
  }
  if (!tether_.weight.empty())
    for (int k = 0; k < terms_.num_unknowns; ++k)
      E += tether_.weight[static_cast<std::size_t>(k)] * (X.row(k) - tether_.anchor.row(k)).squaredNorm();
  return std::max(E, 0.0);
}

void ArapSystem::right_hand_side(const std::vector<Eigen::Matrix3d>& R, geometry::Vertices& b) const {
  b = tether_rhs_;
  for (int c = 0; c < terms_.num_cells; ++c) {
    const auto cu = static_cast<std::size_t>(c);
    for (int q = cell_unknown_begin_[cu]; q < cell_unknown_begin_[cu + 1]; ++q)
      b.row(cell_unknown_[static_cast<std::size_t>(q)]).noalias() += (R[cu] * cell_moment_[static_cast<std::size_t>(q)]).transpose();
  }
}

double ArapSystem::energy(const geometry::Vertices& X) const {
  std::vector<Eigen::Matrix3d> R(static_cast<std::size_t>(terms_.num_cells), Eigen::Matrix3d::Identity());
  return local_step(X, R);
}

ArapSolver::ArapSolver(ArapTerms terms, std::vector<int> constrained, ArapOptions options, ArapTether tether)
    : ArapSolver(std::make_shared<const ArapSystem>(std::move(terms), options, std::move(tether)), std::move(constrained)) {}

ArapSolver::ArapSolver(std::shared_ptr<const ArapSystem> system, std::vector<int> constrained, ConstraintMethod method)
    : system_(std::move(system)), constrained_(std::move(constrained)) {
  const int n = system_->num_unknowns();
  const bool tethered = !system_->tether().weight.empty();
  if (constrained_.empty() && !tethered) throw std::invalid_argument("ARAP needs at least one fixed or handle vertex");
  is_constrained_.assign(static_cast<std::size_t>(n), 0);
  for (const int k : constrained_) {
    if (k < 0 || k >= n) throw std::invalid_argument("constrained index " + std::to_string(k) + " is out of range");
    if (is_constrained_[static_cast<std::size_t>(k)])
      throw std::invalid_argument("vertex " + std::to_string(k) + " is constrained twice");
    is_constrained_[static_cast<std::size_t>(k)] = 1;
  }
  if (!tethered) check_components(system_->terms(), constrained_);
  if (system_->coarse() && system_->options().coarse_rotations)
    coarse_ = system_->coarse()->factor_holding(system_->terms(), system_->tether().weight, constrained_);

  const auto k = static_cast<Eigen::Index>(constrained_.size());
  if (method != ConstraintMethod::Refactor && k > 0) {
    const SparseCholesky* A = system_->prefactored();
    if (!A && method == ConstraintMethod::Capacitance)
      throw std::invalid_argument("ARAP: the capacitance method needs a tethered, positive definite system");
    const bool cheaper = A && 2.0 * static_cast<double>(k) * static_cast<double>(A->factor_nonzeros()) +
                                      30.0 * 3.0 * n * static_cast<double>(k) <
                                  A->factorization_flops();
    if (A && (method == ConstraintMethod::Capacitance || cheaper)) {
      const auto t1 = Clock::now();
      Eigen::MatrixXd E = Eigen::MatrixXd::Zero(n, k);
      for (Eigen::Index c = 0; c < k; ++c) E(constrained_[static_cast<std::size_t>(c)], c) = 1.0;
      W_ = A->solve(E);
      Eigen::MatrixXd S(k, k);
      for (Eigen::Index c = 0; c < k; ++c) S.row(c) = W_.row(constrained_[static_cast<std::size_t>(c)]);
      S_.compute(0.5 * (S + S.transpose()));
      if (S_.info() != Eigen::Success || !W_.allFinite())
        throw std::runtime_error("ARAP: the capacitance matrix of the constraint set is not positive definite");
      prefactored_ = A;
      factor_ms_ = ms_since(t1);
      return;
    }
  }
  // The free block A_FF, eliminated in the system's order with the constrained unknowns
  // left out: no ordering to compute, and less fill than A with those rows and columns
  // masked to identity, whose stored zeros would still be eliminated through.
  const auto t0 = Clock::now();
  std::vector<int> free_index(static_cast<std::size_t>(n), -1);
  for (int k = 0; k < n; ++k)
    if (!is_constrained_[static_cast<std::size_t>(k)]) {
      free_index[static_cast<std::size_t>(k)] = static_cast<int>(free_.size());
      free_.push_back(k);
    }
  const auto n_free = static_cast<Eigen::Index>(free_.size());
  const Eigen::SparseMatrix<double>& A = system_->matrix();
  Eigen::SparseMatrix<double> A_FF(n_free, n_free);
  A_FF.reserve(A.nonZeros());
  for (Eigen::Index c = 0; c < n_free; ++c) {
    A_FF.startVec(c);
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, free_[static_cast<std::size_t>(c)]); it; ++it)
      if (const int r = free_index[static_cast<std::size_t>(it.row())]; r >= 0) A_FF.insertBack(r, c) = it.value();
  }
  A_FF.finalize();
  const auto order_FF = restrict_ordering(system_->ordering(), free_index);
  free_block_ms_ = ms_since(t0);
  const auto t1 = Clock::now();
  if (n_free > 0) cholesky_.emplace(A_FF, order_FF, system_->options().backend);
  factor_ms_ = ms_since(t1);
}

geometry::Vertices ArapSolver::global_step(const geometry::Vertices& b, const geometry::Vertices& coupling, const geometry::Vertices& X_C_full) const {
  geometry::Vertices x;
  if (prefactored_) {
    // x = A⁻¹(b + E μ) with Eᵀx = x_C:  S μ = x_C − Eᵀ A⁻¹ b,  x = A⁻¹b + W μ.
    // Rows F of A x = b + E μ are those of A_FF x_F + A_FC x_C = b_F.
    prefactored_->solve_xyz(b, x);
    Eigen::MatrixXd r(static_cast<Eigen::Index>(constrained_.size()), 3);
    for (std::size_t c = 0; c < constrained_.size(); ++c)
      r.row(static_cast<Eigen::Index>(c)) = X_C_full.row(constrained_[c]) - x.row(constrained_[c]);
    if (!constrained_.empty()) x.noalias() += W_ * S_.solve(r);
    for (const int c : constrained_) x.row(c) = X_C_full.row(c);  // exact, not up to rounding
    return x;
  }
  // A_FF x_F = b_F − A_FC x_C
  geometry::Vertices rhs_F(static_cast<Eigen::Index>(free_.size()), 3), x_F;
  for (std::size_t i = 0; i < free_.size(); ++i) rhs_F.row(static_cast<Eigen::Index>(i)) = b.row(free_[i]) - coupling.row(free_[i]);
  x = X_C_full;
  if (free_.empty()) return x;
  cholesky_->solve_xyz(rhs_F, x_F);
  for (std::size_t i = 0; i < free_.size(); ++i) x.row(free_[i]) = x_F.row(static_cast<Eigen::Index>(i));
  return x;
}

ArapResult ArapSolver::solve(const geometry::Vertices& targets, const geometry::Vertices* initial) const {
  const int n = system_->num_unknowns();
  const auto& options = system_->options();
  if (targets.rows() != static_cast<Eigen::Index>(constrained_.size()))
    throw std::invalid_argument("ARAP solve: " + std::to_string(targets.rows()) + " targets for " +
                                std::to_string(constrained_.size()) + " constrained vertices");
  if (!targets.allFinite()) throw std::invalid_argument("ARAP solve: a target position is not finite");
  if (initial && (initial->rows() != n || !initial->allFinite()))
    throw std::invalid_argument("ARAP solve: the initial guess must have one finite row per unknown");

  ArapResult result;
  result.factor_ms = factor_ms_;
  const auto t_init = Clock::now();
  geometry::Vertices X_C_full = geometry::Vertices::Zero(n, 3);
  for (std::size_t c = 0; c < constrained_.size(); ++c) X_C_full.row(constrained_[c]) = targets.row(static_cast<Eigen::Index>(c));
  const geometry::Vertices coupling = prefactored_ ? geometry::Vertices() : geometry::Vertices(system_->matrix() * X_C_full);
  geometry::Vertices& X = result.X;
  std::vector<Eigen::Matrix3d> R(static_cast<std::size_t>(system_->terms().num_cells), Eigen::Matrix3d::Identity());
  geometry::Vertices b;  // b(R) of the rotations in R, kept with them
  geometry::Vertices x(n, 3);
  if (initial) {
    x = *initial;
    for (const int k : constrained_) x.row(k) = X_C_full.row(k);
  } else {
    system_->right_hand_side(R, b);
    x = global_step(b, coupling, X_C_full);  // Laplacian editing: all rotations identity
  }
  double E = system_->local_step(x, R, R, &b);
  const CoarseSpace* const coarse = coarse_ ? system_->coarse() : nullptr;
  // The global step from the rotations fitted at x: with a coarse space, turned first by its
  // Gauss-Newton step (coarse_space.hpp).
  std::vector<Eigen::Matrix3d> turned;
  geometry::Vertices b_turned;
  const auto next_global = [&]() -> geometry::Vertices {
    if (!coarse) return global_step(b, coupling, X_C_full);
    const Eigen::MatrixXd half_gradient = system_->matrix() * x - b;  // ½ ∇E at (x, R(x))
    const Eigen::VectorXd xi = -coarse_->solve(coarse->project(half_gradient, is_constrained_));
    if (!xi.allFinite()) return global_step(b, coupling, X_C_full);
    turned = R;
    coarse->turn_cells(xi, turned);
    system_->right_hand_side(turned, b_turned);
    return global_step(b_turned, coupling, X_C_full);
  };
  result.energy.push_back(E);
  result.init_ms = ms_since(t_init);

  const auto t_iter = Clock::now();
  // Anderson mixing of successive g = G(x) and f = G(x) − x (flattened).
  const Eigen::Index N = static_cast<Eigen::Index>(n) * 3;
  AndersonMixing anderson(options.anderson ? N : 0, options.anderson_window);

  std::vector<Eigen::Matrix3d> R_candidate;
  geometry::Vertices b_candidate;
  geometry::Vertices f(n, 3), candidate(n, 3);
  geometry::Vertices g = next_global();
  for (int it = 1; it <= options.max_iterations; ++it) {
    f = g - x;
    result.last_update_mm = n > 0 ? f.rowwise().norm().maxCoeff() : 0.0;
    result.iterations = it;
    if (result.last_update_mm < options.tolerance_mm) {
      x = g;
      E = system_->local_step(x, R);
      result.energy.push_back(E);
      result.converged = true;
      break;
    }
    // The mixed iterate, or the plain one g when there is nothing to mix.
    const bool accelerated = options.anderson && anderson.mix(g.data(), f.data(), candidate.data());
    if (accelerated) {
      for (const int k : constrained_) candidate.row(k) = X_C_full.row(k);
    } else {
      candidate = g;
    }
    double E_candidate = system_->local_step(candidate, R, R_candidate, &b_candidate);
    if (accelerated && !(E_candidate < E)) {
      // Safeguard: fall back to the plain local/global step, which cannot raise E.
      ++result.anderson_rejections;
      candidate = g;
      E_candidate = system_->local_step(candidate, R, R_candidate, &b_candidate);
      anderson.restart();
    }
    if (coarse && !(E_candidate <= E)) {
      // The turned rotations did not pay here: the plain step, which cannot raise E.
      ++result.coarse_fallbacks;
      candidate = global_step(b, coupling, X_C_full);
      E_candidate = system_->local_step(candidate, R, R_candidate, &b_candidate);
    }
    std::swap(x, candidate);
    std::swap(R, R_candidate);
    std::swap(b, b_candidate);
    E = E_candidate;
    result.energy.push_back(E);
    g = next_global();
  }
  if (!result.converged && options.max_iterations > 0) {
    x = g;  // the last global solve is the best estimate we have
    result.energy.push_back(system_->local_step(x, R));
  }
  X = std::move(x);
  if (options.max_iterations == 0) result.converged = false;
  result.iterate_ms = ms_since(t_iter);
  return result;
}

ArapTerms mesh_arap_terms(const geometry::Vertices& V, const std::vector<WeightedEdge>& edges) {
  return surface_arap_terms(V, edges, static_cast<int>(V.rows()));
}

}  // namespace evar::deform
