#include "evar/deform/sparse_cholesky.hpp"

#include <Eigen/SparseCholesky>
#include <stdexcept>
#include <variant>

#ifdef EVAR_HAVE_CHOLMOD
#include <Eigen/CholmodSupport>
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

struct SparseCholesky::Impl {
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::AMDOrdering<int>> ldlt;
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

SparseCholesky::~SparseCholesky() = default;
SparseCholesky::SparseCholesky(SparseCholesky&&) noexcept = default;
SparseCholesky& SparseCholesky::operator=(SparseCholesky&&) noexcept = default;

Eigen::MatrixXd SparseCholesky::solve(const Eigen::MatrixXd& B) const {
#ifdef EVAR_HAVE_CHOLMOD
  if (backend_ == CholeskyBackend::Cholmod) return impl_->cholmod->solve(B);
#endif
  return impl_->ldlt.solve(B);
}

}  // namespace evar::deform
