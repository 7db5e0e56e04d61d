#include <gtest/gtest.h>

#include <cmath>

#include "evar/geometry/carm_projection.hpp"
#include "evar/sim/body_phantom.hpp"
#include "evar/sim/tube_mesh.hpp"
#include "evar/sim/xray_render.hpp"
#include "support/carm_view.hpp"

namespace evar::sim {
namespace {

geometry::CArmView view(double primary = 0.0, double secondary = 0.0, int size = 256) {
  return test::carm_view(primary, secondary, size, 0.3 * 1024.0 / size);  // 0.3 mm at 1024
}

TEST(EllipsoidChord, MatchesTheSphereFormula) {
  const Eigen::Vector3d c(1, 2, 3);
  // A ray at distance 6 from the centre of a sphere of radius 10: chord 2·8.
  EXPECT_NEAR(ellipsoid_chord(c, Eigen::Vector3d::Constant(10.0), c + Eigen::Vector3d(6, -50, 0), Eigen::Vector3d::UnitY()), 16.0, 1e-9);
  EXPECT_EQ(ellipsoid_chord(c, Eigen::Vector3d::Constant(10.0), c + Eigen::Vector3d(11, -50, 0), Eigen::Vector3d::UnitY()), 0.0);
  // Starting inside: only the part ahead counts.
  EXPECT_NEAR(ellipsoid_chord(c, Eigen::Vector3d::Constant(10.0), c, Eigen::Vector3d::UnitX()), 10.0, 1e-9);
}

// The path through a closed tube, summed over the detector, is the tube's volume seen
// through the magnification: Σ L · (pixel area at the tube's depth) ≈ volume.
TEST(PathLengths, IntegrateToTheVolumeAndPeakAtTheDiameter) {
  const double r = 8.0;
  const auto tube = tube_mesh({Eigen::Vector3d(0, 0, -40), Eigen::Vector3d(0, 0, 40)}, [&](double) { return r; },
                              TubeOptions{64, 1.0, true});
  const auto v = view();
  cv::Mat L(v.detector_rows, v.detector_cols, CV_64F, cv::Scalar(0.0));
  add_path_lengths({&tube}, Eigen::Matrix4d::Identity(), geometry::projection_matrix(v), L);
  double peak = 0.0, sum = 0.0, negative = 0.0;
  cv::minMaxLoc(L, &negative, &peak);
  sum = cv::sum(L)[0];
  const double pixel_mm = v.col_spacing_mm * v.source_to_isocenter_mm / v.source_to_detector_mm;  // at the isocenter
  EXPECT_NEAR(sum * pixel_mm * pixel_mm, geometry::enclosed_volume(tube), 0.02 * geometry::enclosed_volume(tube));
  EXPECT_NEAR(peak, 2.0 * r, 0.3);  // the divergent ray through the axis is a little oblique
  EXPECT_GT(negative, -1e-6);       // shared edges are counted once: never a spurious entry
}

TEST(XRay, WireShadowLiesWhereTheGeometrySaysAndContrastDarkensTheVessel) {
  const auto v = view(25.0, -10.0);
  const BodyPhantom body = default_body_phantom();
  const auto tube = tube_mesh({Eigen::Vector3d(0, 0, -40), Eigen::Vector3d(0, 0, 40)}, [](double) { return 8.0; });
  XRayContent content;
  content.body = &body;
  content.contrast = {&tube};
  content.wires = {{Eigen::Vector3d(2, 0, -30), Eigen::Vector3d(1, 1, 0), Eigen::Vector3d(-2, 0, 30)}};
  const auto P = geometry::projection_matrix(v);
  const auto plain = expected_xray(v, content);
  content.contrast_fraction = 1.0;
  const auto filled = expected_xray(v, content);
  ASSERT_EQ(plain.wire_truth.size(), 1u);
  const auto mid = geometry::project(P, Eigen::Vector3d(1, 1, 0)).value();
  double best = 1e9;
  for (const auto& p : plain.wire_truth[0]) best = std::min(best, (p - mid).norm());
  EXPECT_LT(best, 0.5);
  // Beside the wire, inside the tube's shadow: iodine (0.05/mm over up to 16 mm) removes
  // 1 - exp(-0.8) of the quanta at the axis, about 55 %; outside the tube nothing changes.
  const auto centre = geometry::project(P, Eigen::Vector3d(0, 0, 20)).value();
  const auto outside = geometry::project(P, Eigen::Vector3d(40, 0, 20)).value();
  const auto at = [](const cv::Mat& m, const Eigen::Vector2d& p) { return m.at<double>(static_cast<int>(std::lround(p.y())), static_cast<int>(std::lround(p.x()))); };
  EXPECT_NEAR(at(filled.quanta, centre) / at(plain.quanta, centre), std::exp(-0.05 * 16.0), 0.03);
  EXPECT_NEAR(at(filled.quanta, outside) / at(plain.quanta, outside), 1.0, 1e-12);
}

TEST(XRay, ReadoutIsDeterministicPerSeedAndNoisy) {
  const auto v = view();
  const BodyPhantom body = default_body_phantom();
  XRayContent content;
  content.body = &body;
  const auto e = expected_xray(v, content);
  const cv::Mat a = detect(e.quanta, {}, 7), b = detect(e.quanta, {}, 7), c = detect(e.quanta, {}, 8);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_INF), 0.0);
  double lo = 0, hi = 0;
  cv::minMaxLoc(a, &lo, &hi);
  EXPECT_LE(hi, 4095.0);
  EXPECT_GT(hi - lo, 500.0);  // bone and tissue give the frame real contrast
}

}  // namespace
}  // namespace evar::sim
