// Ray queries against a closed tube, at the origin and where CT coordinates put patients
// (a metre from the scanner's origin): the same answers in both places, and a point on
// the surface is answered, never aborted.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "evar/geometry/ray_caster.hpp"
#include "evar/sim/tube_mesh.hpp"

using namespace evar;

namespace {

constexpr double kRadius = 10.0;

// A straight closed tube of radius 10 mm along z from 0 to 100 mm, moved by `offset`.
geometry::TriangleMesh tube(const Eigen::Vector3d& offset) {
  std::vector<Eigen::Vector3d> c;
  for (int i = 0; i <= 10; ++i) c.push_back(offset + Eigen::Vector3d(0.0, 0.0, 10.0 * i));
  sim::TubeOptions o;
  o.segments_around = 64;
  o.ring_spacing_mm = 1.0;
  return sim::tube_mesh(c, [](double) { return kRadius; }, o);
}

// Points inside and outside the tube's wall (the 64-gon's inner radius is
// 10 cos(π/64) = 9.988 mm), and whether each is inside.
std::vector<std::pair<Eigen::Vector3d, bool>> probes() {
  std::vector<std::pair<Eigen::Vector3d, bool>> out;
  for (const double z : {5.0, 37.3, 50.0, 91.1})
    for (const double a : {0.1, 1.3, 2.9, 4.4})
      for (const double r : {0.0, 5.0, 9.9, 10.1, 15.0, 40.0})
        out.push_back({Eigen::Vector3d(r * std::cos(a), r * std::sin(a), z), r < 9.95});
  out.push_back({Eigen::Vector3d(0.0, 0.0, -5.0), false});   // beyond the caps
  out.push_back({Eigen::Vector3d(0.0, 0.0, 105.0), false});
  return out;
}

}  // namespace

TEST(RayCaster, TellsInsideFromOutsideTheSameAtTheOriginAndAMetreAway) {
  for (const Eigen::Vector3d& offset : {Eigen::Vector3d::Zero().eval(), Eigen::Vector3d(-150.0, -150.0, -900.0),
                                        Eigen::Vector3d(400.0, -250.0, 1200.0)}) {
    const geometry::RayCaster caster(tube(offset));
    for (const auto& [p, inside] : probes()) {
      EXPECT_EQ(caster.contains(offset + p), inside) << "at " << p.transpose() << ", tube moved by " << offset.transpose();
      // From the axis inside, every ray leaves through the wall once.
      if (inside && p.head<2>().norm() < 1e-9) {
        EXPECT_EQ(caster.crossings(offset + p, Eigen::Vector3d(0.3, 0.4, 0.1)), 1) << offset.transpose();
      }
    }
  }
}

TEST(RayCaster, AHitFarFromTheOriginIsWhereItIsNearIt) {
  const Eigen::Vector3d far(-150.0, -150.0, -900.0);
  const geometry::RayCaster near_caster(tube(Eigen::Vector3d::Zero())), far_caster(tube(far));
  for (const Eigen::Vector3d& d : {Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0.6, 0.8, 0.05), Eigen::Vector3d(-0.2, 0.3, 0.9)}) {
    const Eigen::Vector3d from(1.0, -2.0, 40.0);
    const auto a = near_caster.first_hit(from, d), b = far_caster.first_hit(far + from, d);
    ASSERT_TRUE(a && b);
    EXPECT_EQ(a->face, b->face);
    // Embree holds both tubes relative to their own middle: the same floats, so the same hit.
    EXPECT_LT((b->point - far - a->point).norm(), 1e-6) << d.transpose();
    EXPECT_NEAR(a->t_mm, b->t_mm, 1e-6);
  }
}

// A point exactly on the surface (a vertex, a face's centre) once made the next ray start
// at a small negative distance, which Debian's Embree aborts on.
TEST(RayCaster, PointsOnTheSurfaceAndNegativeBoundsAreAnsweredNotAborted) {
  const Eigen::Vector3d far(-150.0, -150.0, -900.0);
  const geometry::TriangleMesh mesh = tube(far);
  const geometry::RayCaster caster(mesh);
  for (Eigen::Index f = 0; f < mesh.F.rows(); f += 7) {
    const Eigen::Vector3d centre =
        (mesh.V.row(mesh.F(f, 0)) + mesh.V.row(mesh.F(f, 1)) + mesh.V.row(mesh.F(f, 2))).transpose() / 3.0;
    (void)caster.contains(centre);
    (void)caster.contains(mesh.V.row(mesh.F(f, 0)).transpose());
  }
  const Eigen::Vector3d on_axis = far + Eigen::Vector3d(0.0, 0.0, 50.0);
  const auto hit = caster.first_hit(on_axis, Eigen::Vector3d(1, 0, 0), std::numeric_limits<double>::infinity(), -5.0);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->t_mm, kRadius, 0.02);
  EXPECT_FALSE(caster.first_hit(on_axis, Eigen::Vector3d(1, 0, 0), 5.0, 8.0)) << "an empty interval has no hit";
  EXPECT_FALSE(caster.first_hit(on_axis, Eigen::Vector3d(1, 0, 0), std::nan(""), std::nan(""))) << "nor a NaN one";
  EXPECT_EQ(caster.crossings(on_axis, Eigen::Vector3d(0, 0, 0)), 0) << "no direction, no ray";
}
