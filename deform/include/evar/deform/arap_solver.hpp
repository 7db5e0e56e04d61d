#pragma once
// As-rigid-as-possible solver (Sorkine & Alexa 2007) over an ArapTerms energy, with the
// constrained unknowns (handles, fixed vertices) as hard constraints.
//
//   ArapSystem (once per mesh):  A = Σ w a aᵀ (+ tether) assembled, fill-reducing ordering
//                                of its pattern computed;
//   ArapSolver (per constraint   either the free block A_FF (constrained rows and columns
//   set):                        dropped) factored by sparse Cholesky in the system's
//                                elimination order restricted to it, or, for a few constrained
//                                unknowns of a tethered system, A itself factored once per
//                                system and the constraints imposed through the k by k
//                                capacitance matrix S = Eᵀ A⁻¹ E (E: the constrained
//                                columns of I), which is cheaper than a new factorization;
//   solve:                       initial guess by Laplacian editing (all R = I), then
//                                alternating local rotation fits and global solves
//                                A_FF x_F = b_F(R) − A_FC x_C, accelerated by Anderson mixing
//                                with an energy safeguard (Peng et al. 2018) so the energy
//                                never increases, until the largest update is below tolerance;
//                                with a coarse space (coarse_space.hpp) the rotations are
//                                turned by its step before each global solve.
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Sparse>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "evar/deform/arap_system.hpp"
#include "evar/deform/coarse_space.hpp"
#include "evar/deform/sparse_cholesky.hpp"

namespace evar::deform {


struct ArapOptions {
  int max_iterations = 500;      ///< cap on local/global iterations
  double tolerance_mm = 0.01;    ///< stop when the largest vertex update is below this
  bool anderson = true;          ///< Anderson acceleration (off: plain local/global)
  int anderson_window = 5;       ///< number of previous iterates mixed
  /// With a coarse space (ArapSystem's knots): before each global step, turn the rotations
  /// by its Gauss-Newton step (coarse_space.hpp). Off: plain local/global.
  bool coarse_rotations = true;
  CholeskyBackend backend = CholeskyBackend::Default;
};

/// Optional weak tether of unknowns to anchor positions, added to the energy as
/// Σ_k weight_k |x_k − anchor_k|² (no rotation: it ties the shape to where registration
/// put it, so a handle cluster cannot swing the whole vessel through its near-free rigid
/// modes). Empty weight = no tether.
struct ArapTether {
  std::vector<double> weight;  ///< per unknown (dimensionless, like the cotangent weights)
  geometry::Vertices anchor;            ///< per unknown (mm)
};

struct ArapResult {
  geometry::Vertices X;                 ///< all unknowns after the solve (constrained rows = targets)
  int iterations = 0;          ///< local/global iterations after the initial guess
  bool converged = false;      ///< largest update fell below the tolerance
  double last_update_mm = 0.0; ///< largest update of the last iteration
  std::vector<double> energy;  ///< E(x, R(x)) of the initial guess and of every accepted iterate
  int anderson_rejections = 0; ///< accelerated steps refused by the energy safeguard
  int coarse_fallbacks = 0;    ///< steps where the turned rotations raised E and the plain step was taken
  double factor_ms = 0.0;      ///< numeric factorization for this constraint set
  double init_ms = 0.0;        ///< initial guess (Laplacian editing or warm start)
  double iterate_ms = 0.0;     ///< all iterations
};

/// What depends only on the mesh (and skeleton, tether): shared by every constraint set.
class ArapSystem {
 public:
  ArapSystem(ArapTerms terms, ArapOptions options = {}, ArapTether tether = {}, const ArapKnots& knots = {});

  const ArapTerms& terms() const { return terms_; }
  const ArapOptions& options() const { return options_; }
  const ArapTether& tether() const { return tether_; }
  const CoarseSpace* coarse() const { return coarse_ ? &*coarse_ : nullptr; }  ///< null: no knots given
  int num_unknowns() const { return terms_.num_unknowns; }
  double assemble_ms() const { return assemble_ms_; }
  double ordering_ms() const { return ordering_ms_; }

  /// E(X) = min_R E(X, R): the energy of a configuration of all unknowns.
  double energy(const geometry::Vertices& X) const;
  /// E(X, R) with R fitted in place (warm start: R's current content).
  double local_step(const geometry::Vertices& X, std::vector<Eigen::Matrix3d>& R) const;
  /// The same with the warm start `R_warm` and the fitted rotations written to `R` (which
  /// may be R_warm itself); with `b`, also b(R) as right_hand_side() gives it, in the same
  /// pass over the cells while each one's data is in cache.
  double local_step(const geometry::Vertices& X, const std::vector<Eigen::Matrix3d>& R_warm, std::vector<Eigen::Matrix3d>& R,
                    geometry::Vertices* b) const;
  /// b(R) = Σ_t w_t a_t (R_c e_t)ᵀ + tether, for all unknowns (#unknowns by 3).
  void right_hand_side(const std::vector<Eigen::Matrix3d>& R, geometry::Vertices& b) const;

  const Eigen::SparseMatrix<double>& matrix() const { return A_; }  ///< full symmetric A
  /// A itself factored (on first use, once): only a tether makes it positive definite, so
  /// null without one, or when A is singular anyway (a vertex with no face and no area).
  const SparseCholesky* prefactored() const;
  const Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>& ordering() const { return ordering_; }

 private:
  ArapTerms terms_;
  ArapOptions options_;
  ArapTether tether_;
  std::optional<CoarseSpace> coarse_;
  Eigen::SparseMatrix<double> A_;
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> ordering_;
  // b(R) cell by cell: b_k = Σ_c R_c m_ck with m_ck = Σ_{t∈c} w_t a_tk e_t, over the
  // distinct unknowns k of cell c ([cell_unknown_begin_[c], cell_unknown_begin_[c+1])):
  // one product per unknown instead of one per term and a scatter per coefficient.
  std::vector<int> cell_unknown_begin_{0};
  std::vector<int> cell_unknown_;
  std::vector<Eigen::Vector3d> cell_moment_;  ///< m_ck (mm)
  geometry::Vertices tether_rhs_;                      ///< weight_k anchor_k (zero rows without a tether)
  double rest_energy_ = 0.0;  ///< Σ_t w_t |e_t|²
  double assemble_ms_ = 0.0, ordering_ms_ = 0.0;
  mutable std::once_flag prefactor_once_;
  mutable std::optional<SparseCholesky> prefactored_;
};

/// How an ArapSolver imposes its constraint set.
enum class ConstraintMethod {
  Automatic,    ///< the cheaper of the two by operation count (see ArapSolver)
  Refactor,     ///< factor the free block A_FF anew
  Capacitance,  ///< the system's prefactored A and S = Eᵀ A⁻¹ E (tethered systems only)
};

class ArapSolver {
 public:
  /// Builds the system and factors it for `constrained` (unknown indices held at given
  /// targets in solve()). Without a tether every connected component of the term graph
  /// needs a constrained unknown, otherwise std::invalid_argument names a vertex of the
  /// undetermined part.
  ArapSolver(ArapTerms terms, std::vector<int> constrained, ArapOptions options = {}, ArapTether tether = {});
  /// Prepares a shared system for a new constraint set. Automatic picks the capacitance
  /// method when 2·k·nnz(L) (forming A⁻¹E) plus 30 iterations of its 3·n·k correction cost
  /// fewer multiply-adds than a factorization (Σ c_j²): a handful of handles on a
  /// large vessel, not hundreds of bound vertices.
  ArapSolver(std::shared_ptr<const ArapSystem> system, std::vector<int> constrained,
             ConstraintMethod method = ConstraintMethod::Automatic);

  /// `targets`: one row per constrained unknown, in the order given to the constructor.
  /// `initial`: optional warm start for all unknowns (e.g. the previous frame's result).
  ArapResult solve(const geometry::Vertices& targets, const geometry::Vertices* initial = nullptr) const;

  double energy(const geometry::Vertices& X) const { return system_->energy(X); }
  const ArapSystem& system() const { return *system_; }
  const std::vector<int>& constrained() const { return constrained_; }
  double assemble_ms() const { return system_->assemble_ms() + free_block_ms_; }
  double factor_ms() const { return factor_ms_; }
  CholeskyBackend backend() const { return cholesky_ ? cholesky_->backend() : prefactored_->backend(); }
  /// Entries below the diagonal of the factor the iterations solve with (A_FF's, or A's for
  /// the capacitance method); 0 when unknown (CHOLMOD).
  Eigen::Index factor_nonzeros() const {
    return cholesky_ ? cholesky_->factor_nonzeros() : prefactored_ ? prefactored_->factor_nonzeros() : 0;
  }
  ConstraintMethod method() const { return prefactored_ ? ConstraintMethod::Capacitance : ConstraintMethod::Refactor; }

 private:
  /// x solving the global step for the right-hand side b = b(R).
  geometry::Vertices global_step(const geometry::Vertices& b, const geometry::Vertices& coupling, const geometry::Vertices& X_C_full) const;

  std::shared_ptr<const ArapSystem> system_;
  std::vector<int> constrained_;
  std::vector<char> is_constrained_;
  double free_block_ms_ = 0.0, factor_ms_ = 0.0;  // free_block_ms_: extracting A_FF and its order
  std::optional<SparseCholesky> cholesky_;  // A_FF (refactor method)
  std::vector<int> free_;                   // its unknowns: the unconstrained ones, ascending
  // Capacitance method: the system's factor of A, W = A⁻¹E (n by k), S = EᵀW factored.
  const SparseCholesky* prefactored_ = nullptr;
  Eigen::MatrixXd W_;
  Eigen::LLT<Eigen::MatrixXd> S_;
  std::optional<Eigen::LDLT<Eigen::MatrixXd>> coarse_;  // the coarse space's N holding this constraint set
};

/// Plain surface ARAP on a mesh (no skeleton), used by `evarnode arap`.
ArapTerms mesh_arap_terms(const geometry::Vertices& V, const std::vector<WeightedEdge>& edges);

}  // namespace evar::deform
