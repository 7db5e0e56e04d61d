#pragma once
// Anderson acceleration of a fixed-point iteration x ← G(x) (Walker & Ni 2011; for ARAP,
// Peng et al. 2018): from the last m differences of g = G(x) and f = G(x) − x, the mixed
// iterate g − ΔG θ with θ = argmin |f − ΔF θ|, solved by regularised normal equations on
// column-scaled ΔF. The Gram matrix ΔFᵀΔF is renewed one row and column per iteration.
// The caller keeps the safeguard: when the mixed iterate does not lower the energy it
// takes the plain one and calls restart().
#include <Eigen/Core>

namespace evar::deform {

class AndersonMixing {
 public:
  /// `size`: entries of an iterate; `window`: differences kept (m >= 1).
  AndersonMixing(Eigen::Index size, int window);

  /// Records g = G(x) and f = G(x) − x (each `size` entries, contiguous) and writes the
  /// mixed iterate into `mixed` (`size` entries). False, with `mixed` untouched, while there
  /// is no difference yet (the first call after construction or restart()) or when θ is
  /// not finite.
  bool mix(const double* g, const double* f, double* mixed);
  /// Forgets the history (the mixed step was refused).
  void restart();

 private:
  int m_;
  Eigen::MatrixXd dG_, dF_, gram_;
  Eigen::VectorXd prev_g_, prev_f_;
  int history_ = 0, next_col_ = 0;
  bool have_prev_ = false;
};

}  // namespace evar::deform
