#include <gtest/gtest.h>

#include "evar/deform/control_points.hpp"
#include "tube_fixture.hpp"

using namespace evar;

namespace {
struct TubeCase {
  geometry::TriangleMesh mesh = test::straight_tube(60.0, 8.0, 32, 1.0);
  std::vector<Eigen::Vector3d> centerline = test::straight_centerline(60.0);
  geometry::RayCaster caster{mesh};
  deform::RadiusProfile radius = deform::radius_profile(deform::build_skeleton(caster, centerline));
};
}  // namespace

TEST(ControlPoints, DeviceOutsideTheWallGivesHandlesMovedByEquation6) {
  TubeCase tc;
  // Device inside on the axis, then 4 mm outside the wall (x = 12) for z in [20, 40].
  const std::vector<Eigen::Vector3d> device{{0, 0, 55}, {0, 0, 45}, {12, 0, 40}, {12, 0, 20}, {0, 0, 15}, {0, 0, 5}};
  deform::ControlPointOptions opt;
  opt.device_thickness_mm = 0.9;
  const auto handles = deform::select_control_points(tc.mesh, tc.caster, tc.centerline, tc.radius, device, opt);
  // 20 mm outside, handles at least 1.5 median edge lengths apart.
  ASSERT_GE(handles.size(), 6u);
  for (const auto& h : handles) {
    // h on the wall, d beyond it, and h + s lies Δd past d along (d − h). The shift's
    // direction is the ray's; h, recomputed in double from Embree's single-precision
    // barycentrics, lies within about 1e-7 mm of that ray.
    EXPECT_NEAR(h.hit.head<2>().norm(), 8.0, 0.2);
    const Eigen::Vector3d dh = h.device_point - h.hit;
    EXPECT_LT((h.hit + h.shift - (h.device_point + 0.9 * dh.normalized())).norm(), 1e-6);
    EXPECT_NEAR(h.shift.norm(), dh.norm() + 0.9, 1e-6);
    EXPECT_GT(h.device_point.head<2>().norm(), 8.0);
  }
  // Evenly spaced: no two handles closer than the spacing (1.5 x median edge length).
  const double spacing = 1.5 * geometry::median_edge_length(tc.mesh);
  for (std::size_t a = 0; a < handles.size(); ++a)
    for (std::size_t b = a + 1; b < handles.size(); ++b) EXPECT_GE((handles[a].hit - handles[b].hit).norm(), spacing);
}

TEST(ControlPoints, DeviceInsideTheLumenGivesNoHandles) {
  TubeCase tc;
  const std::vector<Eigen::Vector3d> device{{0, 0, 58}, {3, 2, 40}, {-4, 1, 20}, {0, 0, 2}};
  EXPECT_TRUE(deform::select_control_points(tc.mesh, tc.caster, tc.centerline, tc.radius, device, {}).empty());
}

TEST(ControlPoints, DevicePastTheVesselsEndIsNotItsBusiness) {
  TubeCase tc;
  // Entirely beyond the distal end (it belongs to the next vessel down).
  const std::vector<Eigen::Vector3d> device{{15, 0, 70}, {15, 0, 90}};
  EXPECT_TRUE(deform::device_points_in_vessel(tc.centerline, tc.radius, device, {}).empty());
  EXPECT_TRUE(deform::select_control_points(tc.mesh, tc.caster, tc.centerline, tc.radius, device, {}).empty());
}

TEST(ControlPoints, HandleTargetsMoveTheHitTrianglesCorners) {
  TubeCase tc;
  const std::vector<Eigen::Vector3d> device{{12, 0, 40}, {12, 0, 20}};
  const auto handles = deform::select_control_points(tc.mesh, tc.caster, tc.centerline, tc.radius, device, {});
  const auto targets = deform::handle_vertex_targets(tc.mesh, handles);
  ASSERT_FALSE(targets.empty());
  double largest = 0.0;
  for (const auto& h : handles) largest = std::max(largest, h.shift.norm());
  for (const auto& [v, p] : targets) {
    const Eigen::Vector3d shift = p - tc.mesh.V.row(v).transpose();
    EXPECT_GT(shift.x(), 3.0);  // pushed out toward the device at x = 12
    // A mean of handle shifts: at least the radial push 12 + Δd − 8 (less the facet
    // depth), at most the largest (oblique rays near the stretch's ends are longer).
    EXPECT_GE(shift.norm(), 0.9 * (12.0 + 0.9 - 8.0));
    EXPECT_LE(shift.norm(), largest + 1e-9);
  }
}
