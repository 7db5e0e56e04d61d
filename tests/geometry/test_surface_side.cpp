// Which side of a wall a point lies on: closed surfaces everywhere, open tubes beside their
// wall and beyond their openings.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "evar/geometry/surface_side.hpp"

using namespace evar;
using geometry::Side;

namespace {

// A cylinder of radius r along z from 0 to length, open at both ends, normals outward.
geometry::TriangleMesh open_tube(double r, double length, int around = 32, int along = 25) {
  geometry::TriangleMesh m;
  m.V.resize(around * (along + 1), 3);
  for (int j = 0; j <= along; ++j)
    for (int i = 0; i < around; ++i) {
      const double t = 2 * M_PI * i / around;
      m.V.row(j * around + i) << r * std::cos(t), r * std::sin(t), length * j / along;
    }
  m.F.resize(2 * around * along, 3);
  int f = 0;
  for (int j = 0; j < along; ++j)
    for (int i = 0; i < around; ++i) {
      const int a = j * around + i, b = j * around + (i + 1) % around, c = a + around, d = b + around;
      m.F.row(f++) << a, b, d;
      m.F.row(f++) << a, d, c;
    }
  return m;
}

// An axis-aligned closed box [0, s]^3, normals outward.
geometry::TriangleMesh closed_box(double s) {
  geometry::TriangleMesh m;
  m.V.resize(8, 3);
  for (int i = 0; i < 8; ++i) m.V.row(i) << s * (i & 1), s * ((i >> 1) & 1), s * ((i >> 2) & 1);
  m.F.resize(12, 3);
  m.F << 0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5;
  return m;
}

}  // namespace

TEST(SurfaceSide, AClosedSurfaceHasTheRightSideEverywhereCornersAndEdgesIncluded) {
  const geometry::SurfaceSide box(closed_box(10.0));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-5.0, 15.0);
  int checked = 0;
  for (int k = 0; k < 3000; ++k) {
    const Eigen::Vector3d p(u(rng), u(rng), u(rng));
    const bool inside = (p.array() > 0.0).all() && (p.array() < 10.0).all();
    const auto s = box.classify(p);
    ASSERT_EQ(s.side, inside ? Side::Inside : Side::Outside) << p.transpose();
    // The distance outside: to the box.
    if (!inside) {
      const Eigen::Vector3d d = (p.array() - p.array().min(10.0).max(0.0)).matrix();
      EXPECT_NEAR(s.distance_mm, d.norm(), 1e-9);
    }
    ++checked;
  }
  EXPECT_EQ(checked, 3000);
  // Straight out of a corner and an edge, where the closest point is a vertex or an edge.
  EXPECT_EQ(box.classify({-1, -1, -1}).side, Side::Outside);
  EXPECT_EQ(box.classify({-1, 5, -1}).side, Side::Outside);
  EXPECT_EQ(box.classify({0.1, 0.1, 0.1}).side, Side::Inside);
}

TEST(SurfaceSide, AnOpenTubeTellsItsWallFromItsOpenings) {
  const geometry::SurfaceSide tube(open_tube(5.0, 50.0));
  EXPECT_EQ(tube.classify({0, 0, 25}).side, Side::Inside);
  EXPECT_EQ(tube.classify({4, 0, 25}).side, Side::Inside);
  const auto out = tube.classify({7, 0, 25});
  EXPECT_EQ(out.side, Side::Outside);
  EXPECT_NEAR(out.distance_mm, 2.0, 0.02);  // the polygon's chord sits 0.5 % inside the circle
  // Beside the wall at the rim, and beyond the openings (on the axis, and just off it).
  EXPECT_EQ(tube.classify({7, 0, 50.5}).side, Side::Outside);
  EXPECT_EQ(tube.classify({4.5, 0, 49.9}).side, Side::Inside);
  EXPECT_EQ(tube.classify({0, 0, 60}).side, Side::BeyondOpening);
  EXPECT_EQ(tube.classify({0, 0, -3}).side, Side::BeyondOpening);
  EXPECT_EQ(tube.classify({4, 0, 52}).side, Side::BeyondOpening);
  // On the wall counts as inside; a mesh without faces cannot tell.
  EXPECT_EQ(tube.classify({5, 0, 0}).side, Side::Inside);
  geometry::TriangleMesh empty;
  empty.V.resize(0, 3);
  empty.F.resize(0, 3);
  EXPECT_EQ(geometry::SurfaceSide(empty).classify({0, 0, 0}).side, Side::BeyondOpening);
}

// A box whose top face (z = 10) is marked as a cap: it still bounds the inside, but what
// lies outside nearest to it (above it, or past its edges and corners) is beyond an
// opening; beside the other faces it is outside as before.
TEST(SurfaceSide, ACapBoundsTheInsideButWhatLiesPastItIsBeyondAnOpening) {
  const auto box = closed_box(10.0);
  std::vector<char> caps(static_cast<std::size_t>(box.F.rows()), 0);
  for (Eigen::Index f = 0; f < box.F.rows(); ++f)
    caps[static_cast<std::size_t>(f)] = box.V(box.F(f, 0), 2) == 10.0 && box.V(box.F(f, 1), 2) == 10.0 &&
                                        box.V(box.F(f, 2), 2) == 10.0;
  ASSERT_EQ(std::count(caps.begin(), caps.end(), 1), 2);
  const geometry::SurfaceSide capped(box, caps);
  EXPECT_EQ(capped.classify({5, 5, 9.9}).side, Side::Inside);   // just below the cap
  EXPECT_EQ(capped.classify({0.1, 5, 9.8}).side, Side::Inside);  // and in its corner
  EXPECT_EQ(capped.classify({5, 5, 10.5}).side, Side::BeyondOpening);
  EXPECT_EQ(capped.classify({5, -1, 11}).side, Side::BeyondOpening);   // past the cap's edge
  EXPECT_EQ(capped.classify({-1, -1, 11}).side, Side::BeyondOpening);  // and its corner
  EXPECT_EQ(capped.classify({5, -1, 5}).side, Side::Outside);          // beside a wall
  EXPECT_EQ(capped.classify({5, 5, -1}).side, Side::Outside);          // under the floor
  const auto beside = capped.classify({5, -1, 5});
  EXPECT_NEAR(beside.distance_mm, 1.0, 1e-12);
  // Unmarked, the same box is closed everywhere.
  EXPECT_EQ(geometry::SurfaceSide(box).classify({5, 5, 10.5}).side, Side::Outside);
  // One flag per face, or none.
  EXPECT_THROW(geometry::SurfaceSide(box, std::vector<char>(3, 1)), std::invalid_argument);
}

// An open tube's two openings, and the ball round an inside point that stays inside: nine
// tenths of its distance from the wall, cut short where an opening's plane is nearer.
TEST(SurfaceSide, TheBallRoundAnInsidePointKeepsOffTheWallAndTheOpenings) {
  const geometry::SurfaceSide tube(open_tube(5.0, 50.0));
  ASSERT_EQ(tube.openings().size(), 2u);
  for (const auto& o : tube.openings()) {
    EXPECT_NEAR(std::abs(o.normal.z()), 1.0, 1e-9);
    EXPECT_TRUE(std::abs(o.centre.z()) < 1e-9 || std::abs(o.centre.z() - 50.0) < 1e-9) << o.centre.transpose();
    EXPECT_NEAR(o.radius_mm, 5.0, 1e-9);
    EXPECT_NEAR(o.half_thickness_mm, 0.0, 1e-9);
  }
  const auto middle = tube.classify({0, 0, 25});
  ASSERT_EQ(middle.side, Side::Inside);
  EXPECT_NEAR(tube.inside_ball_radius_mm({0, 0, 25}, middle.distance_mm), 0.9 * middle.distance_mm, 1e-12);
  const auto near_end = tube.classify({0, 0, 48});
  ASSERT_EQ(near_end.side, Side::Inside);
  EXPECT_NEAR(tube.inside_ball_radius_mm({0, 0, 48}, near_end.distance_mm), 2.0, 1e-9);
  EXPECT_EQ(geometry::SurfaceSide(closed_box(10.0)).openings().size(), 0u);
}
