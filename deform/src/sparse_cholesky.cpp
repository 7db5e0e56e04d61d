#include "evar/deform/sparse_cholesky.hpp"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#ifdef EVAR_HAVE_CHOLMOD
#include <Eigen/CholmodSupport>
#endif
#ifdef EVAR_HAVE_METIS
#include <iostream>  // Eigen's METIS glue reports failures on std::cerr without including it
#include <Eigen/MetisSupport>
#endif

namespace evar::deform {

bool cholmod_available() {
#ifdef EVAR_HAVE_CHOLMOD
  return true;
#else
  return false;
#endif
}

CholeskyBackend parse_cholesky_backend(const std::string& name) {
  if (name == "default") return CholeskyBackend::Default;
  if (name == "eigen") return CholeskyBackend::EigenLDLT;
  if (name == "cholmod") return CholeskyBackend::Cholmod;
  throw std::invalid_argument("unknown solver '" + name + "' (expected default, eigen or cholmod)");
}

const char* to_string(CholeskyBackend backend) {
  switch (backend) {
    case CholeskyBackend::Default: return "default";
    case CholeskyBackend::EigenLDLT: return "eigen";
    case CholeskyBackend::Cholmod: return "cholmod";
  }
  return "?";
}

namespace {
// Measured in bench/ (docs/BENCHMARKS.md): see there for which is faster and why.
CholeskyBackend resolve(CholeskyBackend b) {
  if (b == CholeskyBackend::Default) return CholeskyBackend::EigenLDLT;
  if (b == CholeskyBackend::Cholmod && !cholmod_available())
    throw std::invalid_argument("this build has no CHOLMOD (install libsuitesparse-dev and rebuild)");
  return b;
}
}  // namespace

bool nested_dissection_available() {
#ifdef EVAR_HAVE_METIS
  return true;
#else
  return false;
#endif
}

Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> fill_reducing_ordering(const Eigen::SparseMatrix<double>& A) {
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> perm;
  // Both want the full symmetric pattern.
  Eigen::SparseMatrix<double> full;
  full = A.selfadjointView<Eigen::Lower>();
#ifdef EVAR_HAVE_METIS
  if (full.rows() >= kNestedDissectionFromUnknowns) {
    Eigen::MetisOrdering<int> metis;
    metis(full, perm);
    if (perm.size() == full.rows()) return perm;  // else METIS failed (it says so on stderr): AMD

  }
#endif
  Eigen::AMDOrdering<int> amd;
  amd(full, perm);
  return perm;
}

Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> restrict_ordering(
    const Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>& ordering, const std::vector<int>& keep_index) {
  if (keep_index.size() != static_cast<std::size_t>(ordering.size()))
    throw std::invalid_argument("restrict_ordering: one index per unknown of the ordering is required");
  const auto kept = static_cast<Eigen::Index>(std::count_if(keep_index.begin(), keep_index.end(), [](int k) { return k >= 0; }));
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> restricted(kept);
  Eigen::Index next = 0;
  for (Eigen::Index t = 0; t < ordering.size(); ++t)  // indices()[t]: the unknown eliminated t-th
    if (const int k = keep_index[static_cast<std::size_t>(ordering.indices()[t])]; k >= 0) {
      if (k >= kept) throw std::invalid_argument("restrict_ordering: the kept unknowns are not numbered 0.." + std::to_string(kept - 1));
      restricted.indices()[next++] = k;
    }
  return restricted;
}

namespace {
// Solves L D Lᵀ y = b for the three coordinate columns in one pass over the factor per
// triangle: the coordinates of an unknown sit next to each other, so each entry of L is
// loaded once, not three times (Eigen sweeps L once per column). At 7.5k vertices L
// (about 280k entries, 3.3 MB with indices) does not fit in L2, so its traffic is the cost.
// `y` holds b in the factor's order, interleaved x0 y0 z0 x1 ...; L strictly lower, CSC.
void solve_ldlt_xyz(const int* outer, const int* inner, const double* value, const double* d, Eigen::Index n,
                    double* y) {
  for (Eigen::Index j = 0; j < n; ++j) {  // L z = b
    const double y0 = y[3 * j], y1 = y[3 * j + 1], y2 = y[3 * j + 2];
    for (int p = outer[j]; p < outer[j + 1]; ++p) {
      double* yi = y + 3 * static_cast<Eigen::Index>(inner[p]);
      const double l = value[p];
      yi[0] -= l * y0;
      yi[1] -= l * y1;
      yi[2] -= l * y2;
    }
  }
  for (Eigen::Index j = 0; j < n; ++j) {  // D w = z
    const double inv = 1.0 / d[j];
    y[3 * j] *= inv;
    y[3 * j + 1] *= inv;
    y[3 * j + 2] *= inv;
  }
  for (Eigen::Index j = n - 1; j >= 0; --j) {  // Lᵀ y = w
    double s0 = y[3 * j], s1 = y[3 * j + 1], s2 = y[3 * j + 2];
    for (int p = outer[j]; p < outer[j + 1]; ++p) {
      const double* yi = y + 3 * static_cast<Eigen::Index>(inner[p]);
      const double l = value[p];
      s0 -= l * yi[0];
      s1 -= l * yi[1];
      s2 -= l * yi[2];
    }
    y[3 * j] = s0;
    y[3 * j + 1] = s1;
    y[3 * j + 2] = s2;
  }
}
// The same for k columns (row-major n by k): the prefactored path's A⁻¹E. Kept apart from
// the three-column sweep on purpose: one template for both made an ARAP iteration 15 %
// slower (1.57 -> 1.80 ms at 7.5k), as the fixed-width version keeps its row in registers.
void solve_ldlt_rows(const int* outer, const int* inner, const double* value, const double* d, Eigen::Index n,
                     Eigen::Index k, double* y) {
  for (Eigen::Index j = 0; j < n; ++j) {
    const double* yj = y + j * k;
    for (int p = outer[j]; p < outer[j + 1]; ++p) {
      double* yi = y + static_cast<Eigen::Index>(inner[p]) * k;
      const double l = value[p];
      for (Eigen::Index c = 0; c < k; ++c) yi[c] -= l * yj[c];
    }
  }
  for (Eigen::Index j = 0; j < n; ++j)
    for (Eigen::Index c = 0; c < k; ++c) y[j * k + c] /= d[j];
  for (Eigen::Index j = n - 1; j >= 0; --j) {
    double* yj = y + j * k;
    for (int p = outer[j]; p < outer[j + 1]; ++p) {
      const double* yi = y + static_cast<Eigen::Index>(inner[p]) * k;
      const double l = value[p];
      for (Eigen::Index c = 0; c < k; ++c) yj[c] -= l * yi[c];
    }
  }
}
}  // namespace

struct SparseCholesky::Impl {
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::AMDOrdering<int>> ldlt;
  // With a given ordering: P A Pᵀ factored in natural order.
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>> ldlt_ordered;
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> perm;  // P⁻¹
  bool ordered = false;
#ifdef EVAR_HAVE_CHOLMOD
  std::unique_ptr<Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower>> cholmod;
#endif
};

SparseCholesky::SparseCholesky(const Eigen::SparseMatrix<double>& A, CholeskyBackend backend)
    : impl_(std::make_unique<Impl>()), backend_(resolve(backend)) {
  if (backend_ == CholeskyBackend::EigenLDLT) {
    impl_->ldlt.compute(A);
    if (impl_->ldlt.info() != Eigen::Success)
      throw std::runtime_error("sparse Cholesky (Eigen LDLT) failed: the ARAP system is not positive definite");
    // LDLT succeeds on some indefinite matrices; a non-positive pivot means a free,
    // unconstrained component (or a broken weight) and would give garbage.
    if ((impl_->ldlt.vectorD().array() <= 0.0).any())
      throw std::runtime_error("sparse Cholesky (Eigen LDLT): the ARAP system is not positive definite");
    return;
  }
#ifdef EVAR_HAVE_CHOLMOD
  impl_->cholmod = std::make_unique<Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower>>();
  impl_->cholmod->compute(A);
  if (impl_->cholmod->info() != Eigen::Success)
    throw std::runtime_error("sparse Cholesky (CHOLMOD) failed: the ARAP system is not positive definite");
#endif
}

SparseCholesky::SparseCholesky(const Eigen::SparseMatrix<double>& A,
                               const Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>& ordering,
                               CholeskyBackend backend)
    : impl_(std::make_unique<Impl>()), backend_(resolve(backend)) {
  if (backend_ != CholeskyBackend::EigenLDLT) {
    *this = SparseCholesky(A, backend_);
    return;
  }
  if (ordering.size() != A.rows()) throw std::invalid_argument("sparse Cholesky: ordering size does not match the matrix");
  // As Eigen does internally: factor C = P⁻¹ A P⁻ᵀ (AMD's P maps new to old indices).
  impl_->perm = ordering.inverse();
  impl_->ordered = true;
  Eigen::SparseMatrix<double> PAPt;
  PAPt.template selfadjointView<Eigen::Lower>() = A.template selfadjointView<Eigen::Lower>().twistedBy(impl_->perm);
  impl_->ldlt_ordered.compute(PAPt);
  if (impl_->ldlt_ordered.info() != Eigen::Success || (impl_->ldlt_ordered.vectorD().array() <= 0.0).any())
    throw std::runtime_error("sparse Cholesky (Eigen LDLT): the ARAP system is not positive definite");
}

double SparseCholesky::factorization_flops() const {
  if (backend_ != CholeskyBackend::EigenLDLT || !impl_->ordered) return 0.0;
  const auto& L = impl_->ldlt_ordered.matrixL().nestedExpression();
  double flops = 0.0;
  for (Eigen::Index j = 0; j < L.outerSize(); ++j) {
    const double c = L.outerIndexPtr()[j + 1] - L.outerIndexPtr()[j];
    flops += c * c;
  }
  return flops;
}

Eigen::Index SparseCholesky::factor_nonzeros() const {
  if (backend_ != CholeskyBackend::EigenLDLT || !impl_->ordered) return 0;
  return impl_->ldlt_ordered.matrixL().nestedExpression().nonZeros();
}

SparseCholesky::~SparseCholesky() = default;
SparseCholesky::SparseCholesky(SparseCholesky&&) noexcept = default;
SparseCholesky& SparseCholesky::operator=(SparseCholesky&&) noexcept = default;

Eigen::MatrixXd SparseCholesky::solve(const Eigen::MatrixXd& B) const {
#ifdef EVAR_HAVE_CHOLMOD
  if (backend_ == CholeskyBackend::Cholmod) return impl_->cholmod->solve(B);
#endif
  if (impl_->ordered && B.cols() == 3) {  // points: the three-column sweep
    geometry::Vertices X;
    solve_xyz(B, X);
    return X;
  }
  if (impl_->ordered && B.cols() > 0) {
    // C = P A Pᵀ is factored: A x = b  ⇔  C (P x) = P b.
    const auto& L = impl_->ldlt_ordered.matrixL().nestedExpression();
    const int* p = impl_->perm.indices().data();
    const Eigen::Index n = B.rows(), k = B.cols();
    std::vector<double> y(static_cast<std::size_t>(k * n));
    for (Eigen::Index c = 0; c < k; ++c)
      for (Eigen::Index i = 0; i < n; ++i) y[static_cast<std::size_t>(k * p[i] + c)] = B(i, c);
    const Eigen::VectorXd D = impl_->ldlt_ordered.vectorD();  // returned by value
    const double* d = D.data();
    solve_ldlt_rows(L.outerIndexPtr(), L.innerIndexPtr(), L.valuePtr(), d, n, k, y.data());
    Eigen::MatrixXd X(n, k);
    for (Eigen::Index c = 0; c < k; ++c)
      for (Eigen::Index i = 0; i < n; ++i) X(i, c) = y[static_cast<std::size_t>(k * p[i] + c)];
    return X;
  }
  if (impl_->ordered) return impl_->perm.transpose() * Eigen::MatrixXd(impl_->ldlt_ordered.solve(impl_->perm * B));
  return impl_->ldlt.solve(B);
}

void SparseCholesky::solve_xyz(const geometry::Vertices& B, geometry::Vertices& X) const {
  if (!impl_->ordered) {
    X = solve(Eigen::MatrixXd(B));
    return;
  }
  const auto& L = impl_->ldlt_ordered.matrixL().nestedExpression();
  const int* p = impl_->perm.indices().data();
  const Eigen::Index n = B.rows();
  thread_local std::vector<double> y;  // reused: one solve per ARAP iteration
  y.resize(static_cast<std::size_t>(3 * n));
  for (Eigen::Index i = 0; i < n; ++i) Eigen::Map<Eigen::RowVector3d>(y.data() + 3 * p[i]) = B.row(i);
  solve_ldlt_xyz(L.outerIndexPtr(), L.innerIndexPtr(), L.valuePtr(), impl_->ldlt_ordered.vectorD().data(), n, y.data());
  X.resize(n, 3);
  for (Eigen::Index i = 0; i < n; ++i) X.row(i) = Eigen::Map<const Eigen::RowVector3d>(y.data() + 3 * p[i]);
}

}  // namespace evar::deform
