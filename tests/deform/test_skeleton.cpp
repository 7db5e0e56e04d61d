#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "evar/deform/skeleton.hpp"
#include "evar/geometry/ray_caster.hpp"
#include "support/energy_descent.hpp"
#include "tube_fixture.hpp"

using namespace evar;

TEST(Skeleton, PlanesEveryFiveMillimetresWithSixWallHitsAtTheRadius) {
  const auto m = test::straight_tube(60.0, 8.0, 32, 1.0);
  const geometry::RayCaster caster(m);
  const auto sk = deform::build_skeleton(caster, test::straight_centerline(60.0));
  ASSERT_EQ(sk.centres.size(), 12u);  // 60 mm / 5 mm, centred: 2.5, 7.5, ..., 57.5
  EXPECT_EQ(sk.spokes.size(), 12u * 6u);
  EXPECT_NEAR(sk.centres.front().z(), 2.5, 1e-9);
  for (std::size_t k = 1; k < sk.centres.size(); ++k)
    EXPECT_NEAR((sk.centres[k] - sk.centres[k - 1]).norm(), 5.0, 1e-9);
  // Wall hits lie on the polygonal wall: between the inscribed apothem and the radius.
  for (const auto& s : sk.spokes) {
    const double r = s.hit.head<2>().norm();
    EXPECT_GE(r, 8.0 * std::cos(M_PI / 32) - 1e-6);
    EXPECT_LE(r, 8.0 + 1e-6);
    EXPECT_NEAR(s.hit.z(), sk.centres[static_cast<std::size_t>(s.centre)].z(), 1e-6);  // in the plane
  }
  EXPECT_NEAR(deform::radius_profile(sk).at(30.0), 8.0, 0.1);
}

TEST(Skeleton, PlanesWhoseRaysMissTheMeshAreDropped) {
  const auto m = test::straight_tube(30.0, 8.0);
  const geometry::RayCaster caster(m);
  // A centerline that runs 40 mm past the tube's end: planes out there hit nothing.
  const std::vector<Eigen::Vector3d> cl{{0, 0, 0}, {0, 0, 70}};
  const auto sk = deform::build_skeleton(caster, cl);
  for (const auto& c : sk.centres) EXPECT_LE(c.z(), 30.0);
  EXPECT_GE(sk.centres.size(), 5u);
}

namespace {
// Bends a closed tube by holding its bottom end and turning its top end by 90 degrees
// about a horizontal axis (handles: the 3 mm at each end), then returns the relative
// change of enclosed volume.
double bent_tube_volume_change(bool with_skeleton) {
  const double L = 80.0, r = 10.0;
  const auto m = test::straight_tube(L, r, 32, 1.5);
  const int n = static_cast<int>(m.V.rows());
  const geometry::RayCaster caster(m);
  const auto sk = deform::build_skeleton(caster, test::straight_centerline(L));
  const int centres = with_skeleton ? static_cast<int>(sk.centres.size()) : 0;
  deform::ArapTerms terms = deform::surface_arap_terms(m.V, deform::cotangent_weights(m), n + centres);
  if (with_skeleton) deform::append_skeleton_terms(terms, m, sk, n, 1.0);
  // Quarter-circle bend: the top end goes to the end of an arc of length L.
  const double R = L / (M_PI / 2);
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Vector3d top_centre_target(R, 0.0, R);
  std::vector<int> handles;
  geometry::Vertices targets(0, 3);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d v = m.V.row(i).transpose();
    Eigen::Vector3d target;
    if (v.z() < 3.0) {
      target = v;
    } else if (v.z() > L - 3.0) {
      target = top_centre_target + Q * (v - Eigen::Vector3d(0, 0, L));
    } else {
      continue;
    }
    handles.push_back(i);
    targets.conservativeResize(targets.rows() + 1, 3);
    targets.row(targets.rows() - 1) = target.transpose();
  }
  deform::ArapOptions opt;
  opt.tolerance_mm = 1e-3;
  const auto res = deform::ArapSolver(std::move(terms), handles, opt).solve(targets);
  EXPECT_TRUE(res.converged);
  geometry::TriangleMesh out{res.X.topRows(n), m.F};
  const double v0 = geometry::enclosed_volume(m), v1 = geometry::enclosed_volume(out);
  return (v1 - v0) / v0;
}
}  // namespace

TEST(Skeleton, KeepsABentTubesVolumeBetterThanPlainArap) {
  const double plain = std::abs(bent_tube_volume_change(false));
  const double skeletal = std::abs(bent_tube_volume_change(true));
  RecordProperty("volume_change_plain", std::to_string(plain));
  RecordProperty("volume_change_skeleton", std::to_string(skeletal));
  std::cout << "relative volume change: plain ARAP " << plain << ", skeleton-based " << skeletal << "\n";
  EXPECT_LT(skeletal, 0.5 * plain);
}

TEST(Skeleton, EnergyNeverIncreasesWithSkeletonAndTetherAsDeformRunsIt) {
  // The production configuration: surface + skeleton terms, a tether (ℓ = 50 mm), device
  // like handles on one side only, Anderson on.
  const auto m = test::straight_tube(80.0, 10.0, 32, 1.5);
  const int n = static_cast<int>(m.V.rows());
  const geometry::RayCaster caster(m);
  const auto sk = deform::build_skeleton(caster, test::straight_centerline(80.0));
  const int centres = static_cast<int>(sk.centres.size());
  deform::ArapTerms terms = deform::surface_arap_terms(m.V, deform::cotangent_weights(m), n + centres);
  deform::append_skeleton_terms(terms, m, sk, n, 1.0);
  deform::ArapTether tether;
  tether.weight.assign(static_cast<std::size_t>(n + centres), 0.0);
  tether.anchor = geometry::Vertices::Zero(n + centres, 3);
  tether.anchor.topRows(n) = m.V;
  for (int i = 0; i < n; ++i) tether.weight[static_cast<std::size_t>(i)] = 2.0 / (50.0 * 50.0);  // ~2 mm² per vertex
  std::vector<int> handles;
  geometry::Vertices targets(0, 3);
  for (int i = 0; i < n; ++i)
    if (m.V(i, 0) > 8.0 && m.V(i, 2) > 30.0 && m.V(i, 2) < 50.0) {  // one side, middle
      handles.push_back(i);
      targets.conservativeResize(targets.rows() + 1, 3);
      targets.row(targets.rows() - 1) = m.V.row(i) + Eigen::RowVector3d(6.0, 0.0, 2.0);
    }
  ASSERT_GT(handles.size(), 10u);
  deform::ArapOptions opt;
  opt.tolerance_mm = 1e-4;
  const auto r = deform::ArapSolver(std::move(terms), handles, opt, tether).solve(targets);
  EXPECT_TRUE(r.converged);
  ASSERT_GE(r.energy.size(), 3u);
  EXPECT_TRUE(evar::test::energy_never_rises(r.energy));
  EXPECT_LT(r.energy.back(), r.energy.front());
}
