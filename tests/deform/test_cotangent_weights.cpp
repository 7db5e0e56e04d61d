#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>

#include "evar/deform/cotangent_weights.hpp"

using evar::deform::cotangent_laplacian;
using evar::deform::cotangent_weights;
using evar::geometry::TriangleMesh;

namespace {
TriangleMesh two_triangles(const Eigen::Vector3d& apex0, const Eigen::Vector3d& apex1) {
  TriangleMesh m;
  m.V.resize(4, 3);
  m.V << 0, 0, 0, 1, 0, 0, apex0.x(), apex0.y(), apex0.z(), apex1.x(), apex1.y(), apex1.z();
  m.F.resize(2, 3);
  m.F << 0, 1, 2, 1, 0, 3;
  return m;
}
double weight_of(const std::vector<evar::deform::WeightedEdge>& edges, int i, int j) {
  for (const auto& e : edges)
    if (e.i == i && e.j == j) return e.w;
  ADD_FAILURE() << "edge " << i << "-" << j << " missing";
  return NAN;
}
}  // namespace

TEST(CotangentWeights, SharedEdgeOfTwoEquilateralTrianglesIsCot60) {
  const double h = std::sqrt(3.0) / 2.0;
  const auto edges = cotangent_weights(two_triangles({0.5, h, 0}, {0.5, -h, 0}));
  ASSERT_EQ(edges.size(), 5u);
  const double cot60 = 1.0 / std::sqrt(3.0);
  EXPECT_NEAR(weight_of(edges, 0, 1), cot60, 1e-12);         // (cot60 + cot60) / 2
  EXPECT_NEAR(weight_of(edges, 0, 2), 0.5 * cot60, 1e-12);   // boundary: one angle
}

TEST(CotangentWeights, ObtuseOppositeAnglesGivePositiveFlooredWeight) {
  // Apexes close to the shared edge: both opposite angles near 180 degrees, cot sum < 0.
  const auto edges = cotangent_weights(two_triangles({0.5, 0.05, 0}, {0.5, -0.05, 0}));
  const double w = weight_of(edges, 0, 1);
  EXPECT_GT(w, 0.0);
  EXPECT_DOUBLE_EQ(w, evar::deform::CotangentOptions{}.w_floor);
}

TEST(CotangentWeights, DegenerateTrianglesNeverGiveNaN) {
  // A zero-area triangle (collinear) and a triangle with two coincident corners.
  TriangleMesh m;
  m.V.resize(5, 3);
  m.V << 0, 0, 0, 1, 0, 0, 2, 0, 0, 0, 1, 0, 0, 1, 0;
  m.F.resize(3, 3);
  m.F << 0, 1, 2, 0, 1, 3, 1, 3, 4;
  for (const auto& e : cotangent_weights(m)) {
    EXPECT_TRUE(std::isfinite(e.w)) << e.i << "-" << e.j;
    EXPECT_GT(e.w, 0.0);
  }
}

TEST(CotangentLaplacian, IsSymmetricWithZeroRowSums) {
  const double h = std::sqrt(3.0) / 2.0;
  const auto m = two_triangles({0.5, h, 0.2}, {0.4, -h, -0.3});
  const Eigen::MatrixXd L = Eigen::MatrixXd(cotangent_laplacian(m));
  EXPECT_LT((L - L.transpose()).norm(), 1e-14);
  EXPECT_LT(L.rowwise().sum().cwiseAbs().maxCoeff(), 1e-14);
  // Positive semidefinite: smallest eigenvalue is the constant null vector's zero.
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(L);
  EXPECT_GT(eig.eigenvalues()(0), -1e-12);
  EXPECT_GT(eig.eigenvalues()(1), 1e-6);
}
