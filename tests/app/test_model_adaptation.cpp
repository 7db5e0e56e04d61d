// The last guard before a model reaches the screen: a deformation result with a vertex,
// landmark or device point that is not finite is refused by name (the node then keeps
// the last good model and says so), never drawn.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>
#include <string>

#include "model_adaptation.hpp"
#include "support/error_message.hpp"

using evar::app::AdaptationError;
using evar::app::AdaptedModel;
using evar::app::check_finite;
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
