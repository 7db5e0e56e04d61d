// The last guard before a model reaches the screen: a deformation result with a vertex,
// landmark or device point that is not finite is refused by name (the node then keeps
// the last good model and says so), never drawn.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include "evar/geometry/carm_projection.hpp"
#include "evar/node/model_adaptation.hpp"
#include "evar/sim/example_scene.hpp"
#include "support/error_message.hpp"

using evar::node::AdaptationError;
using evar::node::AdaptedModel;
using evar::node::check_finite;
using testing::HasSubstr;

namespace {

AdaptedModel finite_model() {
  AdaptedModel m;
  m.deformation.vessels.resize(2);
  m.deformation.reports.resize(2);
  m.deformation.reports[0].name = "aorta";
  m.deformation.reports[1].name = "iliac_right";
  for (auto& v : m.deformation.vessels) {
    v.mesh.V.resize(3, 3);
    v.mesh.V << 0, 0, 0, 10, 0, 0, 0, 10, 0;
  }
  m.deformation.landmarks = {{"renal_left", {1, 2, 3}}, {"internal_iliac_right", {4, 5, 6}}};
  m.reconstruction.points = {{0, 0, 0}, {0, 0, 1}};
  return m;
}

std::string refusal(const AdaptedModel& m) {
  return evar::test::error_message<AdaptationError>([&] { check_finite(m); }, "accepted");
}

}  // namespace

TEST(ModelAdaptation, ANonFiniteResultIsRefusedByName) {
  constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(refusal(finite_model()), "accepted");
  auto vertex = finite_model();
  vertex.deformation.vessels[1].mesh.V(2, 1) = nan;
  EXPECT_THAT(refusal(vertex), HasSubstr("vessel iliac_right vertex 2 is not finite"));
  auto landmark = finite_model();
  landmark.deformation.landmarks[0].position_lps.z() = std::numeric_limits<double>::infinity();
  EXPECT_THAT(refusal(landmark), HasSubstr("landmark renal_left is not finite"));
  auto device = finite_model();
  device.reconstruction.points[1].x() = nan;
  EXPECT_THAT(refusal(device), HasSubstr("device point 1 is not finite"));
}

namespace {

std::vector<Eigen::Vector2d> projected(const evar::geometry::ProjectionMatrix& P, const evar::geometry::Polyline& curve) {
  std::vector<Eigen::Vector2d> out;
  for (const auto& X : evar::geometry::resample(curve, 0.25)) out.push_back(*evar::geometry::project(P, X));
  return out;
}

evar::geometry::CArmView lao(double primary_deg) {
  evar::geometry::CArmView v;
  v.primary_angle_deg = primary_deg;
  v.source_to_detector_mm = 1200;
  v.source_to_isocenter_mm = 800;
  v.detector_cols = v.detector_rows = 1024;
  v.row_spacing_mm = v.col_spacing_mm = 0.4;
  return v;
}

}  // namespace

// A crossover catheter (up the right iliac, over the bifurcation, down the left) in a
// LAO/RAO pair reads two ways (its limbs at the same heights); the node takes the reading
// that lies in the vessels, and refuses when both do.
TEST(ModelAdaptation, OfTwoReadingsTheOneInTheVesselsIsTheDevice) {
  namespace geo = evar::geometry;
  const auto example = evar::sim::make_example_scene({});
  const auto scene = evar::sim::to_scene(example);
  const evar::deform::SceneDeformer deformer(scene);
  const auto& right = example.vessel("iliac_right").centerline;
  const auto& left = example.vessel("iliac_left").centerline;
  geo::Polyline crossover(right.rbegin(), right.rend() - 10);  // access low on the right …
  crossover.insert(crossover.end(), left.begin() + 10, left.end());  // … tip low on the left
  const auto P1 = geo::projection_matrix(lao(30)), P2 = geo::projection_matrix(lao(-30));
  auto c2 = projected(P2, crossover);
  std::reverse(c2.begin(), c2.end());  // traced from the other end in view 2
  const auto readings = geo::reconstruct_two_view_readings(projected(P1, crossover), P1, c2, P2);
  ASSERT_EQ(readings.size(), 2u) << "the example's crossover is not symmetric enough to read two ways";
  const auto chosen = evar::node::reading_in_the_vessels(readings, deformer, 5.0);
  double worst = 0.0;
  for (const auto& p : readings[chosen].points) worst = std::max(worst, geo::project_onto(crossover, p).distance_mm);
  EXPECT_LT(worst, 1.0);
  // The same reading whichever order they come in.
  const std::vector<geo::Reconstruction> swapped{readings[1], readings[0]};
  EXPECT_EQ(evar::node::reading_in_the_vessels(swapped, deformer, 5.0), 1 - chosen);
  EXPECT_LT(evar::node::mean_outside_lumen_mm(readings[chosen].points, deformer), 0.5);
  EXPECT_GT(evar::node::mean_outside_lumen_mm(readings[1 - chosen].points, deformer), 10.0);
  // Two readings both in the vessels (2 mm apart) cannot be told apart: refused, saying why.
  auto near = readings[chosen];
  for (auto& p : near.points) p += Eigen::Vector3d(2.0, 0.0, 0.0);
  const std::vector<geo::Reconstruction> both_inside{readings[chosen], near};
  EXPECT_THAT(evar::test::error_message<AdaptationError>(
                  [&] { evar::node::reading_in_the_vessels(both_inside, deformer, 5.0); }, "accepted"),
              HasSubstr("both lie in the vessels or near them"));
}

// A curve that follows another structure for part of its length (an ECG lead crossing the
// wire in both views reconstructs with no residual) is refused before it bends the
// vessels; a device the vessels must move a few cm to contain is not.
TEST(ModelAdaptation, ADeviceRunningFarOutsideTheVesselsIsRefused) {
  const auto example = evar::sim::make_example_scene({});
  const auto scene = evar::sim::to_scene(example);
  const evar::deform::SceneDeformer deformer(scene);
  const evar::node::AdaptationOptions options;
  EXPECT_NO_THROW(evar::node::check_in_the_vessels(example.device, deformer, options));
  auto moved = example.device;  // the whole device 30 mm to the side: a strong deformation, still plausible
  for (auto& p : moved) p.y() += 30.0;
  EXPECT_NO_THROW(evar::node::check_in_the_vessels(moved, deformer, options));
  // The wire goes on 250 mm above the top of an infrarenal segmentation, up the aorta's
  // axis (a third of its points over 50 mm past the centerline's end: refused before).
  auto onwards = example.device;
  const auto& aortic = example.vessel("aorta").centerline;
  const Eigen::Vector3d up = (aortic.front() - aortic[5]).normalized();
  for (int k = 1; k <= 250; ++k) onwards.insert(onwards.begin(), onwards.front() + up);
  EXPECT_NO_THROW(evar::node::check_in_the_vessels(onwards, deformer, options));
  auto hijacked = example.device;  // its last third leaves along a lead, 3 mm forwards per point
  const std::size_t from = hijacked.size() * 2 / 3;
  for (std::size_t k = from; k < hijacked.size(); ++k)
    hijacked[k] = hijacked[from] + Eigen::Vector3d(0.0, -3.0 * static_cast<double>(k - from), 0.0);
  std::reverse(hijacked.begin(), hijacked.end());
  EXPECT_THAT(evar::test::error_message<AdaptationError>(
                  [&] { evar::node::check_in_the_vessels(hijacked, deformer, options); }, "accepted"),
              HasSubstr("outside the preoperative vessels"));
}
