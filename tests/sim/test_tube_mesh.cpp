#include "evar/sim/tube_mesh.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>
#include <stdexcept>
#include <utility>
#include <vector>

namespace {

using evar::geometry::TriangleMesh;
using evar::sim::TubeOptions;
using Points = std::vector<Eigen::Vector3d>;
constexpr double kPi = std::numbers::pi;

// Counts of each directed edge (a, b) over all faces.
std::map<std::pair<int, int>, int> directed_edges(const TriangleMesh& mesh) {
  std::map<std::pair<int, int>, int> edges;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int c = 0; c < 3; ++c) ++edges[{mesh.F(f, c), mesh.F(f, (c + 1) % 3)}];
  return edges;
}

// Closed, manifold and consistently oriented: every directed edge once, its reverse once.
::testing::AssertionResult closed_and_oriented(const TriangleMesh& mesh) {
  const auto edges = directed_edges(mesh);
  for (const auto& [e, count] : edges) {
    if (count != 1) return ::testing::AssertionFailure() << "edge " << e.first << "-" << e.second << " used " << count << " times in one direction";
    const auto twin = edges.find({e.second, e.first});
    if (twin == edges.end()) return ::testing::AssertionFailure() << "edge " << e.first << "-" << e.second << " has no twin (boundary)";
  }
  return ::testing::AssertionSuccess();
}

Points straight_line(double length, int points) {
  Points p;
  for (int i = 0; i < points; ++i) p.emplace_back(0.0, 0.0, length * i / (points - 1));
  return p;
}

// Quarter circle of radius R in the xz plane, starting along +z, sampled every ~1 mm.
Points planar_arc(double R) {
  Points p;
  const int n = static_cast<int>(std::ceil(R * kPi / 2.0));
  for (int i = 0; i <= n; ++i) {
    const double a = (kPi / 2.0) * i / n;
    p.emplace_back(R * (1.0 - std::cos(a)), 0.0, R * std::sin(a));
  }
  return p;
}

double inscribed_area(int n, double r) { return 0.5 * n * r * r * std::sin(2.0 * kPi / n); }

TEST(TubeMesh, CappedTubeIsClosedManifoldAndConsistentlyOriented) {
  const TubeOptions options{24, 2.0, true};
  const auto mesh = evar::sim::tube_mesh(planar_arc(60.0), [](double s) { return 6.0 + 0.02 * s; }, options);
  EXPECT_TRUE(closed_and_oriented(mesh));
  // Euler characteristic of a sphere.
  const auto edges = directed_edges(mesh);
  EXPECT_EQ(mesh.V.rows() - static_cast<Eigen::Index>(edges.size() / 2) + mesh.F.rows(), 2);
}

TEST(TubeMesh, StraightTubeVolumeIsTheStaggeredRingSolidInsideTheCylinder) {
  const double r = 10.0, length = 100.0;
  const int n = 32;
  const auto mesh = evar::sim::tube_mesh(straight_line(length, 11), [r](double) { return r; }, {n, 2.5, true});
  const double volume = evar::geometry::enclosed_volume(mesh);
  // Each band between two rings turned by pi/N is an antiprism; by the prismatoid rule
  // its volume is h/6 (A + A + 4 A_mid) = h N r^2 sin(pi/N) (1 + 2 cos(pi/N)) / 3.
  const double antiprisms = length * n * r * r * std::sin(kPi / n) * (1.0 + 2.0 * std::cos(kPi / n)) / 3.0;
  EXPECT_NEAR(volume, antiprisms, 1e-9 * antiprisms);
  // Outward orientation and the discretization bounds: inscribed N-gon prism < V < cylinder.
  EXPECT_GT(volume, inscribed_area(n, r) * length);
  EXPECT_LT(volume, kPi * r * r * length);
}

TEST(TubeMesh, CurvedTubeVolumeFollowsPappus) {
  // A tube swept along a curve (radius of curvature > tube radius) has volume A * L.
  const double R = 60.0, r = 8.0, length = R * kPi / 2.0;
  const int n = 64;
  const auto mesh = evar::sim::tube_mesh(planar_arc(R), [r](double) { return r; }, {n, 0.5, true});
  const double volume = evar::geometry::enclosed_volume(mesh);
  // The centerline is a 1 mm chord polygon of the arc (length shorter by < 1e-4 relative)
  // and the cross-section lies between the inscribed N-gon and the circle.
  EXPECT_GT(volume, inscribed_area(n, r) * length * (1.0 - 1e-3));
  EXPECT_LT(volume, kPi * r * r * length);
}

TEST(TubeMesh, PlanarCenterlineGivesUntwistedRingsPerpendicularToTheCurve) {
  const double R = 40.0, r = 5.0;
  const int n = 16;
  const auto centerline = planar_arc(R);
  const auto mesh = evar::sim::tube_mesh(centerline, [r](double) { return r; }, {n, 1.0, false});
  const int rings = static_cast<int>(mesh.V.rows()) / n;
  ASSERT_EQ(rings * n, mesh.V.rows());
  for (int k = 0; k < rings; ++k) {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (int j = 0; j < n; ++j) centre += mesh.V.row(k * n + j).transpose();
    centre /= n;
    // The ring centre is on the arc and every ring vertex at distance r from it.
    EXPECT_NEAR((centre - Eigen::Vector3d(R, 0.0, 0.0)).norm(), R, 1e-2) << "ring " << k;
    for (int j = 0; j < n; ++j)
      EXPECT_NEAR((mesh.V.row(k * n + j).transpose() - centre).norm(), r, 1e-9);
    // A rotation-minimizing frame on a planar curve keeps its normal in the plane: vertex
    // 0 of an unturned ring stays in y = 0; a twisting frame would move it out.
    if (k % 2 == 0) {
      EXPECT_NEAR(mesh.V(k * n, 1), 0.0, 1e-9) << "ring " << k;
    }
  }
}

TEST(TubeMesh, OpenTubeHasTwoBoundaryLoopsAndNoCapVertices) {
  const int n = 12;
  const TubeOptions options{n, 1.0, false};
  const auto mesh = evar::sim::tube_mesh(straight_line(20.0, 3), [](double) { return 3.0; }, options);
  EXPECT_EQ(mesh.V.rows(), 21 * n);
  EXPECT_EQ(mesh.V.rows(), evar::sim::tube_vertex_count(20.0, options));
  const auto edges = directed_edges(mesh);
  int boundary = 0;
  for (const auto& [e, count] : edges) {
    EXPECT_EQ(count, 1);
    if (!edges.contains({e.second, e.first})) ++boundary;
  }
  EXPECT_EQ(boundary, 2 * n);
}

TEST(TubeMesh, ResolutionHelperMeetsVertexTargetsWithNearEquilateralTriangles) {
  const double length = 150.0, r = 11.0;
  for (const int target : {7500, 30000, 120000}) {
    const TubeOptions options = evar::sim::tube_options_for_vertex_count(length, r, target);
    const auto mesh = evar::sim::tube_mesh(straight_line(length, 151), [r](double) { return r; }, options);
    EXPECT_EQ(mesh.V.rows(), evar::sim::tube_vertex_count(length, options));
    // Rounding the ring count costs at most N/2 vertices.
    EXPECT_LE(std::abs(mesh.V.rows() - target), options.segments_around / 2 + 1) << target;
    // Side triangles (not the cap fans): all edges within 5% of each other.
    double shortest = 1e300, longest = 0.0;
    for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
      if (mesh.F.row(f).maxCoeff() >= mesh.V.rows() - 2) continue;
      for (int c = 0; c < 3; ++c) {
        const double e = (mesh.V.row(mesh.F(f, c)) - mesh.V.row(mesh.F(f, (c + 1) % 3))).norm();
        shortest = std::min(shortest, e);
        longest = std::max(longest, e);
      }
    }
    EXPECT_LT(longest / shortest, 1.05) << target;
  }
}

TEST(TubeMesh, ResolutionHelperOnACenterlineUsesTheMeanRadius) {
  const auto centerline = planar_arc(80.0);
  const auto radius = [](double s) { return 4.0 + s / 40.0; };
  const auto options = evar::sim::tube_options_for_vertex_count(centerline, radius, 5000);
  const auto mesh = evar::sim::tube_mesh(centerline, radius, options);
  EXPECT_NEAR(static_cast<double>(mesh.V.rows()), 5000.0, options.segments_around / 2.0 + 1.0);
  EXPECT_TRUE(closed_and_oriented(mesh));
}

TEST(TubeMesh, PerPointRadiiInterpolateAlongArcLength) {
  // A cone from r = 10 to r = 5 over 60 mm: volume of the frustum pi h (R^2 + R r + r^2) / 3,
  // scaled by the inscribed polygon's area ratio.
  const Points centerline = straight_line(60.0, 4);
  const std::vector<double> radii{10.0, 25.0 / 3.0, 20.0 / 3.0, 5.0};
  const int n = 128;
  const auto mesh = evar::sim::tube_mesh(centerline, radii, {n, 1.0, true});
  EXPECT_TRUE(closed_and_oriented(mesh));
  const double frustum = kPi * 60.0 * (100.0 + 50.0 + 25.0) / 3.0;
  const double polygon = inscribed_area(n, 1.0) / kPi;
  EXPECT_NEAR(evar::geometry::enclosed_volume(mesh), frustum * polygon, 1e-3 * frustum);
  EXPECT_THROW(evar::sim::tube_mesh(centerline, std::vector<double>{1.0, 2.0}, {}), std::invalid_argument);
}

TEST(TubeMesh, RejectsDegenerateInput) {
  const auto one = [](double) { return 1.0; };
  EXPECT_THROW(evar::sim::tube_mesh(Points{{0, 0, 0}}, one), std::invalid_argument);
  EXPECT_THROW(evar::sim::tube_mesh(Points{{0, 0, 0}, {0, 0, 0}}, one), std::invalid_argument);
  EXPECT_THROW(evar::sim::tube_mesh(straight_line(10, 2), one, {2, 1.0, true}), std::invalid_argument);
  EXPECT_THROW(evar::sim::tube_mesh(straight_line(10, 2), one, {8, 0.0, true}), std::invalid_argument);
  EXPECT_THROW(evar::sim::tube_mesh(straight_line(10, 2), [](double s) { return 5.0 - s; }), std::invalid_argument);
  EXPECT_THROW(evar::sim::tube_mesh(straight_line(10, 2), [](double) { return std::nan(""); }), std::invalid_argument);
  EXPECT_THROW(evar::sim::tube_options_for_vertex_count(10.0, 1.0, 7), std::invalid_argument);
  EXPECT_THROW(evar::sim::tube_options_for_vertex_count(0.0, 1.0, 1000), std::invalid_argument);
}

TEST(EnclosedVolume, UnitCubeIsOneAndFlipsSignWithOrientation) {
  TriangleMesh cube;
  cube.V.resize(8, 3);
  for (int i = 0; i < 8; ++i) cube.V.row(i) << (i & 1), (i >> 1) & 1, (i >> 2) & 1;
  cube.F.resize(12, 3);
  cube.F << 0, 2, 1, 1, 2, 3,  // z = 0, facing -z
      4, 5, 6, 5, 7, 6,        // z = 1
      0, 1, 4, 1, 5, 4,        // y = 0
      2, 6, 3, 3, 6, 7,        // y = 1
      0, 4, 2, 2, 4, 6,        // x = 0
      1, 3, 5, 3, 7, 5;        // x = 1
  ASSERT_TRUE(closed_and_oriented(cube));
  EXPECT_NEAR(evar::geometry::enclosed_volume(cube), 1.0, 1e-15);
  // Independent of where the origin is.
  cube.V.rowwise() += Eigen::RowVector3d(100.0, -50.0, 7.0);
  EXPECT_NEAR(evar::geometry::enclosed_volume(cube), 1.0, 1e-11);
  cube.F.col(1).swap(cube.F.col(2));
  EXPECT_NEAR(evar::geometry::enclosed_volume(cube), -1.0, 1e-11);
}

}  // namespace
