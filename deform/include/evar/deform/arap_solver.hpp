#pragma once
// As-rigid-as-possible solver (Sorkine & Alexa 2007) over an ArapTerms energy, with the
// constrained unknowns (handles, fixed vertices) as hard constraints:
//   precomputation: A = Σ w a aᵀ assembled, split into free (F) and constrained (C) parts,
//                   A_FF factored once by sparse Cholesky;
//   solve:          initial guess by Laplacian editing (all R = I), then alternating local
//                   rotation fits and global solves A_FF x_F = b_F(R) − A_FC x_C, accelerated
//                   by Anderson mixing with an energy safeguard (Peng et al. 2018) so the
//                   energy never increases, until the largest update is below tolerance.
#include <Eigen/Core>
#include <optional>
#include <vector>

#include "evar/deform/arap_system.hpp"
#include "evar/deform/sparse_cholesky.hpp"

namespace evar::deform {

using Positions = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;  ///< rows: points (mm)

struct ArapOptions {
  int max_iterations = 500;      ///< cap on local/global iterations
  double tolerance_mm = 0.01;    ///< stop when the largest vertex update is below this
  bool anderson = true;          ///< Anderson acceleration (off: plain local/global)
  int anderson_window = 5;       ///< number of previous iterates mixed
  CholeskyBackend backend = CholeskyBackend::Default;
};

/// Optional weak tether of unknowns to anchor positions, added to the energy as
/// Σ_k weight_k |x_k − anchor_k|² (no rotation: it ties the shape to where registration
/// put it, so a handle cluster cannot swing the whole vessel through its near-free rigid
/// modes). Empty weight = no tether.
struct ArapTether {
  std::vector<double> weight;  ///< per unknown (mm⁻² · mm² = dimensionless, like w)
  Positions anchor;            ///< per unknown (mm)
};

struct ArapResult {
  Positions X;                 ///< all unknowns after the solve (constrained rows = targets)
  int iterations = 0;          ///< local/global iterations after the initial guess
  bool converged = false;      ///< largest update fell below the tolerance
  double last_update_mm = 0.0; ///< largest update of the last iteration
  std::vector<double> energy;  ///< E(x, R(x)) of the initial guess and of every accepted iterate
  int anderson_rejections = 0; ///< accelerated steps refused by the energy safeguard
  double init_ms = 0.0;        ///< initial guess (Laplacian editing or warm start)
  double iterate_ms = 0.0;     ///< all iterations
};

class ArapSolver {
 public:
  /// Assembles and factors. `constrained` lists unknown indices held at given targets in
  /// solve(); every connected component of the term graph needs at least one, otherwise
  /// the problem has no unique solution and std::invalid_argument says which component.
  ArapSolver(ArapTerms terms, std::vector<int> constrained, ArapOptions options = {}, ArapTether tether = {});

  /// `targets`: one row per constrained unknown, in the order given to the constructor.
  /// `initial`: optional warm start for all unknowns (e.g. the previous frame's result).
  ArapResult solve(const Positions& targets, const Positions* initial = nullptr) const;

  /// E(X) = min_R E(X, R): the ARAP energy of a configuration of all unknowns.
  double energy(const Positions& X) const;

  const ArapTerms& terms() const { return terms_; }
  const std::vector<int>& constrained() const { return constrained_; }
  double assemble_ms() const { return assemble_ms_; }
  double factor_ms() const { return factor_ms_; }
  CholeskyBackend backend() const { return cholesky_->backend(); }

 private:
  double local_step(const Positions& X, std::vector<Eigen::Matrix3d>& R) const;
  Eigen::MatrixXd global_step(const std::vector<Eigen::Matrix3d>& R, const Eigen::MatrixXd& fixed_rhs) const;

  ArapTerms terms_;
  std::vector<int> constrained_;
  std::vector<int> free_;          ///< unknown index of each free row
  std::vector<int> free_row_;      ///< free row of each unknown, or -1
  ArapOptions options_;
  Eigen::SparseMatrix<double> A_FC_;
  ArapTether tether_;
  Eigen::MatrixXd tether_rhs_;     ///< weight_k · anchor_k for the free rows
  double rest_energy_ = 0.0;       ///< Σ_t w_t |e_t|²
  double assemble_ms_ = 0.0, factor_ms_ = 0.0;
  std::optional<SparseCholesky> cholesky_;
};

/// Plain surface ARAP on a mesh (no skeleton), used by `evarnode arap`.
ArapTerms mesh_arap_terms(const Positions& V, const std::vector<WeightedEdge>& edges);

}  // namespace evar::deform
