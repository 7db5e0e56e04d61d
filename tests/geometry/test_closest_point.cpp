// Closest points on a mesh: the pruned searches give exactly the brute-force answer.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "evar/geometry/closest_point.hpp"
#include "evar/geometry/ray_caster.hpp"

using namespace evar;

namespace {

// A wavy sheet of 40 x 40 quads (1.5 mm), unevenly stretched so faces differ in size.
geometry::TriangleMesh wavy_sheet() {
  constexpr int n = 41;
  geometry::TriangleMesh m;
  m.V.resize(n * n, 3);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double x = 1.5 * i + 0.01 * i * i, y = 1.5 * j;
      m.V.row(i * n + j) << x, y, 4.0 * std::sin(0.2 * x) * std::cos(0.15 * y);
    }
  m.F.resize(2 * (n - 1) * (n - 1), 3);
  int f = 0;
  for (int i = 0; i + 1 < n; ++i)
    for (int j = 0; j + 1 < n; ++j) {
      const int a = i * n + j, b = a + 1, c = a + n, d = c + 1;
      m.F.row(f++) << a, c, b;
      m.F.row(f++) << b, c, d;
    }
  return m;
}

geometry::SurfacePoint brute_force(const geometry::TriangleMesh& m, const Eigen::Vector3d& p) {
  geometry::SurfacePoint best;
  best.distance_mm = std::numeric_limits<double>::infinity();
  for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
    const Eigen::Vector3d a = m.V.row(m.F(f, 0)).transpose(), b = m.V.row(m.F(f, 1)).transpose(),
                          c = m.V.row(m.F(f, 2)).transpose();
    const Eigen::Vector3d w = geometry::closest_point_on_triangle(p, a, b, c);
    const Eigen::Vector3d q = w[0] * a + w[1] * b + w[2] * c;
    if ((p - q).norm() < best.distance_mm) best = {static_cast<int>(f), w, q, (p - q).norm()};
  }
  return best;
}

}  // namespace

TEST(ClosestPoint, PrunedSearchesAgreeWithTheBruteForceScan) {
  const auto mesh = wavy_sheet();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> near(-3.0, 3.0), wide(-20.0, 90.0);
  // A cluster (a vessel's end) and scattered points, some far above and beside the sheet.
  std::vector<Eigen::Vector3d> points;
  for (int k = 0; k < 60; ++k) points.emplace_back(30.0 + near(rng), 25.0 + near(rng), near(rng));
  for (int k = 0; k < 20; ++k) points.emplace_back(wide(rng), wide(rng), wide(rng) - 35.0);
  const auto batch = geometry::closest_points_on_mesh(mesh, points);
  ASSERT_EQ(batch.size(), points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto truth = brute_force(mesh, points[i]);
    const auto one = geometry::closest_point_on_mesh(mesh, points[i]);
    // The same distance; the same point (ties between faces sharing it may name either).
    EXPECT_NEAR(one.distance_mm, truth.distance_mm, 1e-12) << "point " << i;
    EXPECT_NEAR(batch[i].distance_mm, truth.distance_mm, 1e-12) << "point " << i;
    EXPECT_LT((one.point - truth.point).norm(), 1e-9) << "point " << i;
    EXPECT_LT((batch[i].point - truth.point).norm(), 1e-9) << "point " << i;
    const Eigen::Vector3d a = mesh.V.row(mesh.F(batch[i].face, 0)).transpose(),
                          b = mesh.V.row(mesh.F(batch[i].face, 1)).transpose(),
                          c = mesh.V.row(mesh.F(batch[i].face, 2)).transpose();
    const auto& w = batch[i].barycentric;
    EXPECT_LT((w[0] * a + w[1] * b + w[2] * c - batch[i].point).norm(), 1e-9) << "point " << i;
  }
  EXPECT_TRUE(geometry::closest_points_on_mesh(mesh, {}).empty());
}

// The BVH's point query gives the scan's answer, also for a mesh a metre from the origin
// (the BVH holds floats about the mesh's centre) and with a search radius.
TEST(ClosestPoint, TheRayCastersPointQueryAgreesWithTheScan) {
  for (const double offset_mm : {0.0, 1000.0}) {
    auto mesh = wavy_sheet();
    mesh.V.col(2).array() += offset_mm;
    const geometry::RayCaster caster(mesh);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> wide(-20.0, 90.0);
    for (int k = 0; k < 200; ++k) {
      const Eigen::Vector3d p(wide(rng), wide(rng), offset_mm + wide(rng) - 35.0);
      const auto truth = brute_force(mesh, p);
      const auto found = caster.closest_point(p);
      ASSERT_TRUE(found) << "point " << k;
      EXPECT_NEAR(found->distance_mm, truth.distance_mm, 1e-9) << "point " << k;
      EXPECT_LT((found->point - truth.point).norm(), 1e-6) << "point " << k;
      // Within a radius: found exactly when the closest point lies within it.
      const auto within = caster.closest_point(p, truth.distance_mm + 1e-6);
      ASSERT_TRUE(within) << "point " << k;
      EXPECT_NEAR(within->distance_mm, truth.distance_mm, 1e-9);
      if (truth.distance_mm > 0.01) {
        EXPECT_FALSE(caster.closest_point(p, truth.distance_mm - 0.01)) << "point " << k;
      }
    }
  }
  const geometry::RayCaster caster(wavy_sheet());
  EXPECT_FALSE(caster.closest_point({std::nan(""), 0.0, 0.0}));
  EXPECT_FALSE(caster.closest_point({0.0, 0.0, 0.0}, -1.0));
}
