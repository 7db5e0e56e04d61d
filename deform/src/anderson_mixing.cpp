#include "anderson_mixing.hpp"

#include <Eigen/Cholesky>
#include <algorithm>

namespace evar::deform {

AndersonMixing::AndersonMixing(Eigen::Index size, int window)
    : m_(window), dG_(size, window), dF_(size, window), gram_(window, window), prev_g_(size), prev_f_(size) {}

bool AndersonMixing::mix(const double* g, const double* f, double* mixed) {
  const Eigen::Index N = prev_g_.size();
  const Eigen::Map<const Eigen::VectorXd> gv(g, N), fv(f, N);
  if (have_prev_) {
    dG_.col(next_col_) = gv - prev_g_;
    dF_.col(next_col_) = fv - prev_f_;
    history_ = std::min(history_ + 1, m_);
    for (int j = 0; j < history_; ++j) gram_(next_col_, j) = gram_(j, next_col_) = dF_.col(next_col_).dot(dF_.col(j));
    next_col_ = (next_col_ + 1) % m_;
  }
  prev_g_ = gv;
  prev_f_ = fv;
  have_prev_ = true;
  if (history_ == 0) return false;
  // θ = argmin |f − ΔF θ|, via regularized normal equations on column-scaled ΔF.
  const auto dFh = dF_.leftCols(history_);
  Eigen::VectorXd scale = gram_.diagonal().head(history_).cwiseSqrt();
  for (int j = 0; j < history_; ++j) scale(j) = scale(j) > 0.0 ? 1.0 / scale(j) : 0.0;
  Eigen::MatrixXd M = scale.asDiagonal() * gram_.topLeftCorner(history_, history_) * scale.asDiagonal();
  M.diagonal().array() += 1e-10;
  const Eigen::VectorXd theta = scale.asDiagonal() * M.ldlt().solve(scale.asDiagonal() * (dFh.transpose() * fv));
  if (!theta.allFinite()) return false;
  Eigen::Map<Eigen::VectorXd> out(mixed, N);
  out = gv;
  out.noalias() -= dG_.leftCols(history_) * theta;
  return true;
}

void AndersonMixing::restart() {
  history_ = 0;
  next_col_ = 0;
  have_prev_ = false;
}

}  // namespace evar::deform
