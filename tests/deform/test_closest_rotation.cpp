#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <limits>
#include <random>
#include <vector>

#include "closest_rotation.hpp"

using evar::deform::closest_rotation;
using evar::deform::closest_rotation_svd;

namespace {
bool is_rotation(const Eigen::Matrix3d& R) {
  return (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-9 && std::abs(R.determinant() - 1.0) < 1e-9;
}
// The objective being maximized.
double objective(const Eigen::Matrix3d& R, const Eigen::Matrix3d& A) { return (R.transpose() * A).trace(); }
Eigen::Matrix3d random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
}
}  // namespace

TEST(ClosestRotation, MatchesSvdOnRandomMatricesFromColdAndWarmStarts) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int trial = 0; trial < 500; ++trial) {
    Eigen::Matrix3d A;
    for (int k = 0; k < 9; ++k) A(k / 3, k % 3) = n(rng);
    const Eigen::Matrix3d ref = closest_rotation_svd(A);
    for (const Eigen::Matrix3d& warm : {Eigen::Matrix3d::Identity().eval(), random_rotation(rng)}) {
      const Eigen::Matrix3d R = closest_rotation(A, warm);
      ASSERT_TRUE(is_rotation(R));
      EXPECT_NEAR(objective(R, A), objective(ref, A), 1e-9 * A.norm()) << "trial " << trial;
    }
  }
}

TEST(ClosestRotation, RecoversTheRotationOfARotatedStretch) {
  std::mt19937_64 rng(11);
  const Eigen::Matrix3d Q = random_rotation(rng);
  const Eigen::Matrix3d S = Eigen::Vector3d(3.0, 2.0, 0.5).asDiagonal();
  EXPECT_LT((closest_rotation(Q * S) - Q).norm(), 1e-9);
}

TEST(ClosestRotation, RankTwoCovarianceOfAPlanarOneRingGivesTheInPlaneRotation) {
  // Planar one-ring rotated by 40 degrees about z: A = Σ e' eᵀ has rank 2.
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  for (int k = 0; k < 6; ++k) {
    const Eigen::Vector3d e(std::cos(k * 1.0472), std::sin(k * 1.0472), 0.0);
    A += (Q * e) * e.transpose();
  }
  const Eigen::Matrix3d R = closest_rotation(A);
  EXPECT_TRUE(is_rotation(R));
  EXPECT_LT((R - Q).norm(), 1e-8);
}

TEST(ClosestRotation, NeverReturnsAReflection) {
  const Eigen::Matrix3d mirror = Eigen::Vector3d(1.0, 1.0, -1.0).asDiagonal();
  const Eigen::Matrix3d R = closest_rotation(mirror * Eigen::Vector3d(3.0, 2.0, 1.0).asDiagonal().toDenseMatrix());
  EXPECT_TRUE(is_rotation(R));
  EXPECT_LT((R - Eigen::Matrix3d::Identity()).norm(), 1e-9);  // drop the smallest axis' flip
}

TEST(ClosestRotation, WarmStartHalfATurnAwayStillFindsTheMaximum) {
  const Eigen::Matrix3d A = Eigen::Vector3d(3.0, 2.0, 1.0).asDiagonal();
  const Eigen::Matrix3d warm = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  EXPECT_LT((closest_rotation(A, warm) - Eigen::Matrix3d::Identity()).norm(), 1e-9);
}

TEST(ClosestRotation, ClosedFormMatchesSvd) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::Matrix3d A;
    for (int k = 0; k < 9; ++k) A(k / 3, k % 3) = n(rng);
    const Eigen::Matrix3d R = evar::deform::closest_rotation_closed_form(A);
    ASSERT_TRUE(is_rotation(R));
    EXPECT_NEAR(objective(R, A), objective(closest_rotation_svd(A), A), 1e-9 * A.norm()) << "trial " << trial;
  }
}

TEST(RefineRotation, OneStepSquaresTheErrorOfAWarmStart) {
  // ARAP's local step relies on this: the rotation error after a step is about the
  // square of the error before it, so it vanishes as the iteration converges.
  std::mt19937_64 rng(3);
  const Eigen::Matrix3d S = Eigen::Vector3d(3.0, 2.0, 0.2).asDiagonal();  // nearly planar ring
  for (const double error_rad : {1e-2, 1e-3, 1e-4}) {
    const Eigen::Matrix3d Q = random_rotation(rng);
    const Eigen::Vector3d axis = Eigen::Vector3d::Random().normalized();
    const Eigen::Matrix3d warm = Q * Eigen::AngleAxisd(error_rad, axis).toRotationMatrix();
    const Eigen::Matrix3d R = evar::deform::refine_rotation(Q * S, warm);
    ASSERT_TRUE(is_rotation(R));
    const double left_rad = Eigen::AngleAxisd(Q.transpose() * R).angle();
    EXPECT_LT(left_rad, 5.0 * error_rad * error_rad) << "start " << error_rad;
  }
}

TEST(RefineRotation, FarFromTheMaximumItSolvesExactly) {
  std::mt19937_64 rng(9);
  const Eigen::Matrix3d Q = random_rotation(rng);
  const Eigen::Matrix3d A = Q * Eigen::Vector3d(3.0, 2.0, 1.0).asDiagonal();
  const Eigen::Matrix3d warm = Q * Eigen::AngleAxisd(2.5, Eigen::Vector3d::UnitY()).toRotationMatrix();
  EXPECT_LT((evar::deform::refine_rotation(A, warm) - Q).norm(), 1e-9);
}

TEST(RefineRotation, TheBatchedStepGivesEachCellWhatTheSingleOneGives) {
  // The local step fits eight cells at a time (refine_rotations); every cell, whether its
  // Newton step is accepted or falls back (zero, non-finite or mirrored A, a warm start far
  // off), must get refine_rotation's answer, also when R overwrites the warm starts.
  std::mt19937_64 rng(17);
  std::normal_distribution<double> n(0.0, 1.0);
  constexpr int kCells = 8 * 6 + 5;  // whole lanes and a remainder
  std::vector<Eigen::Matrix3d> A(kCells), warm(kCells);
  for (int c = 0; c < kCells; ++c) {
    const Eigen::Matrix3d Q = random_rotation(rng);
    const Eigen::Matrix3d S = Eigen::Vector3d(3.0, 2.0, 0.3 + 0.1 * (c % 5)).asDiagonal();
    A[c] = Q * S;
    const Eigen::Vector3d axis = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
    const double off_rad = (c % 4 == 0) ? 0.5 : 0.02;  // every fourth outside Newton's regime
    warm[c] = Q * Eigen::AngleAxisd(off_rad, axis).toRotationMatrix();
  }
  A[3].setZero();
  A[9](1, 1) = std::numeric_limits<double>::quiet_NaN();
  A[14] = -A[14];  // det < 0
  A[20] *= 1e-200;  // tiny but valid
  std::vector<Eigen::Matrix3d> expected(kCells);
  for (int c = 0; c < kCells; ++c) expected[c] = evar::deform::refine_rotation(A[c], warm[c]);
  std::vector<Eigen::Matrix3d> R(kCells);
  evar::deform::refine_rotations(A.data(), warm.data(), R.data(), kCells);
  for (int c = 0; c < kCells; ++c) EXPECT_LT((R[c] - expected[c]).norm(), 1e-12) << "cell " << c;
  evar::deform::refine_rotations(A.data(), warm.data(), warm.data(), kCells);  // in place
  for (int c = 0; c < kCells; ++c) EXPECT_LT((warm[c] - expected[c]).norm(), 1e-12) << "cell " << c << " in place";
}
