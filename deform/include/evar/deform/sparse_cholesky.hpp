#pragma once
// Sparse Cholesky factorization of the ARAP system, factored once and solved every
// iteration for the three coordinate columns at once.
#include <Eigen/Core>
#include <Eigen/Sparse>
#include <memory>
#include <string>
#include <vector>

#include "evar/geometry/triangle_mesh.hpp"

namespace evar::deform {

enum class CholeskyBackend {
  Default,     ///< the faster one measured on this project's benchmarks (docs/BENCHMARKS.md)
  EigenLDLT,   ///< Eigen::SimplicialLDLT with the ordering below
  Cholmod,     ///< SuiteSparse CHOLMOD supernodal LL^T (when built with it)
};

/// From this many unknowns on, the ordering is METIS nested dissection (when the build has
/// METIS), below it AMD. Measured on the example vessels (docs/BENCHMARKS.md): nested
/// dissection leaves 20 % fewer entries in L at 7.5k vertices, 25 % at 30k and 40 % at
/// 120k, but costs 6-8 times as long to compute (once per scene): at 7.5k that outweighs
/// what the solves save over a live sequence's first dozen calls, at 30k it is repaid
/// within a few calls.
inline constexpr long kNestedDissectionFromUnknowns = 20000;

/// Whether this build orders large systems by nested dissection (METIS).
bool nested_dissection_available();

/// Fill-reducing ordering of the symmetric pattern of A (lower triangle read): AMD, or
/// METIS nested dissection from kNestedDissectionFromUnknowns unknowns on.
Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> fill_reducing_ordering(const Eigen::SparseMatrix<double>& A);

/// `ordering` (of all n unknowns, as fill_reducing_ordering gives it) restricted to the
/// unknowns with keep_index[k] >= 0, numbered keep_index[k]: the order that eliminates
/// the submatrix of those unknowns in the same sequence, with no fill it would not have.
Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> restrict_ordering(
    const Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>& ordering, const std::vector<int>& keep_index);

CholeskyBackend parse_cholesky_backend(const std::string& name);  ///< "default", "eigen", "cholmod"
const char* to_string(CholeskyBackend backend);
bool cholmod_available();

class SparseCholesky {
 public:
  /// Factors A (symmetric positive definite; only the lower triangle is read).
  /// Throws std::runtime_error if A is not positive definite.
  SparseCholesky(const Eigen::SparseMatrix<double>& A, CholeskyBackend backend = CholeskyBackend::Default);
  /// Same, with a fill-reducing ordering computed once for A's sparsity pattern (see
  /// fill_reducing_ordering), so repeated factorizations of matrices with that pattern
  /// skip the ordering. CHOLMOD ignores it and orders itself.
  SparseCholesky(const Eigen::SparseMatrix<double>& A, const Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>& ordering,
                 CholeskyBackend backend = CholeskyBackend::Default);
  ~SparseCholesky();
  SparseCholesky(SparseCholesky&&) noexcept;
  SparseCholesky& operator=(SparseCholesky&&) noexcept;

  /// X = A^{-1} B for an n by k right-hand side.
  Eigen::MatrixXd solve(const Eigen::MatrixXd& B) const;
  /// The same for points (rows x y z), as the ARAP iterations keep them: no copy to columns
  /// and back, as the factor's sweep works on interleaved coordinates anyway.
  void solve_xyz(const geometry::Vertices& B, geometry::Vertices& X) const;
  CholeskyBackend backend() const { return backend_; }
  /// Σ_j c_j² over the columns of L (c_j its entries below the diagonal): the cost of a
  /// numeric factorization in multiply-adds. 0 when not known (CHOLMOD, or no ordering given).
  double factorization_flops() const;
  /// Entries of L below the diagonal: a triangular solve costs 2 per entry and column.
  Eigen::Index factor_nonzeros() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  CholeskyBackend backend_;
};

}  // namespace evar::deform
