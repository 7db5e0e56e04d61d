// Anderson mixing on its own: on a linear contraction it is GMRES in disguise, so a window
// as large as the problem reaches the fixed point in about as many steps as there are
// unknowns, where the plain iteration needs hundreds.
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "anderson_mixing.hpp"

namespace {

using evar::deform::AndersonMixing;

// G(x) = M x + c with M symmetric, eigenvalues 0.9, 0.8, ..., 0.4 (a contraction).
struct Linear {
  Eigen::MatrixXd M;
  Eigen::VectorXd c, fixed_point;
  Linear() {
    const Eigen::MatrixXd Q = Eigen::HouseholderQR<Eigen::MatrixXd>(Eigen::MatrixXd::Random(6, 6)).householderQ();
    Eigen::VectorXd lambda(6);
    lambda << 0.9, 0.8, 0.7, 0.6, 0.5, 0.4;
    M = Q * lambda.asDiagonal() * Q.transpose();
    c = Eigen::VectorXd::LinSpaced(6, 1.0, 6.0);
    fixed_point = (Eigen::MatrixXd::Identity(6, 6) - M).lu().solve(c);
  }
  Eigen::VectorXd G(const Eigen::VectorXd& x) const { return M * x + c; }
};

// Iterations until |x − x*| < 1e-9, at most `cap`.
int iterations_to_fixed_point(const Linear& p, AndersonMixing* anderson, int cap) {
  Eigen::VectorXd x = Eigen::VectorXd::Zero(6);
  for (int it = 1; it <= cap; ++it) {
    const Eigen::VectorXd g = p.G(x);
    const Eigen::VectorXd f = g - x;
    Eigen::VectorXd next = g;
    if (anderson) anderson->mix(g.data(), f.data(), next.data());
    x = next;
    if ((x - p.fixed_point).norm() < 1e-9) return it;
  }
  return cap + 1;
}

TEST(AndersonMixing, AWindowAsLargeAsTheProblemReachesALinearFixedPointInAboutAsManySteps) {
  const Linear p;
  AndersonMixing anderson(6, 6);
  const int mixed = iterations_to_fixed_point(p, &anderson, 1000);
  const int plain = iterations_to_fixed_point(p, nullptr, 1000);
  EXPECT_LE(mixed, 10);   // 6 unknowns, one step to start the history, rounding
  EXPECT_GE(plain, 150);  // 0.9^k · |x0 − x*| < 1e-9
}

TEST(AndersonMixing, MixesNothingUntilItHasADifferenceAndAgainAfterARestart) {
  const Linear p;
  AndersonMixing anderson(6, 3);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(6), out = Eigen::VectorXd::Constant(6, -7.0);
  Eigen::VectorXd g = p.G(x), f = g - x;
  EXPECT_FALSE(anderson.mix(g.data(), f.data(), out.data()));
  EXPECT_EQ(out, Eigen::VectorXd::Constant(6, -7.0));  // untouched
  x = g;
  g = p.G(x);
  f = g - x;
  EXPECT_TRUE(anderson.mix(g.data(), f.data(), out.data()));
  anderson.restart();
  out.setConstant(-7.0);
  EXPECT_FALSE(anderson.mix(g.data(), f.data(), out.data()));
  EXPECT_EQ(out, Eigen::VectorXd::Constant(6, -7.0));
}

}  // namespace
