// How much of a device the vessels leave outside: stretches through the wall are measured,
// the lumen, the openings and the seam between two vessels are not counted.
#include <gtest/gtest.h>

#include <cmath>

#include "evar/deform/device_containment.hpp"
#include "tube_fixture.hpp"

using namespace evar;

namespace {

geometry::TriangleMesh open_tube(const std::vector<Eigen::Vector3d>& centerline, double r) {
  return sim::tube_mesh(centerline, [r](double) { return r; }, {32, 1.0, false});
}

}  // namespace

TEST(DeviceContainment, ADeviceInTheLumenIsContainedAndOnePastTheOpeningsIsNotJudged) {
  const auto tube = open_tube({{0, 0, 0}, {0, 0, 100}}, 8.0);
  // Along the axis and on through both openings, 20 mm past each.
  const geometry::Polyline device{{1, 0, -20}, {1, 0, 120}};
  const auto c = deform::measure_device_containment({{"vessel", &tube}}, device);
  EXPECT_NEAR(c.device_length_mm, 140.0, 1e-9);
  EXPECT_EQ(c.outside_length_mm, 0.0);
  EXPECT_EQ(c.outside_max_depth_mm, 0.0);
  EXPECT_TRUE(c.stretches.empty());
  EXPECT_NEAR(c.unjudged_length_mm, 40.0, 1.0);
  EXPECT_FALSE(deform::leaves_device_outside(c));
  EXPECT_EQ(deform::describe_outside(c), "");
}

TEST(DeviceContainment, AStretchThroughTheWallIsMeasuredWithItsDepthAndVessel) {
  const auto tube = open_tube({{0, 0, 0}, {0, 0, 100}}, 8.0);
  // In the lumen, out through the wall to 12 mm off the axis (4 mm beyond the wall) over
  // z = 40..60, and back in.
  const geometry::Polyline device{{0, 0, 10}, {0, 0, 30}, {12, 0, 40}, {12, 0, 60}, {0, 0, 70}, {0, 0, 90}};
  const auto c = deform::measure_device_containment({{"iliac_right", &tube}}, device);
  ASSERT_EQ(c.stretches.size(), 1u);
  EXPECT_NEAR(c.outside_max_depth_mm, 4.0, 0.05);  // the 32-gon's chords lie 0.5 % inside the circle
  // Outside from where the ramps cross r = 8 (2/3 of the way up each 15.6 mm ramp) across
  // the 20 mm top: the last third of each ramp and the top, to a sample step.
  const double ramp = std::hypot(12.0, 10.0);
  EXPECT_NEAR(c.outside_length_mm, 20.0 + 2.0 * ramp / 3.0, 0.6);
  EXPECT_EQ(c.stretches[0].nearest_vessel, "iliac_right");
  EXPECT_NEAR(c.stretches[0].from_mm, 20.0 + 2.0 * ramp / 3.0, 0.6);
  EXPECT_TRUE(deform::leaves_device_outside(c));
  const std::string text = deform::describe_outside(c);
  EXPECT_NE(text.find("of the device lies outside the vessels, up to 4.0 mm beyond the wall of 'iliac_right'"),
            std::string::npos)
      << text;
}

// An aorta whose lower end opens into an iliac that begins inside it: the device runs from
// one into the other through the seam without being outside either.
TEST(DeviceContainment, TheSeamBetweenTwoVesselsIsNotOutside) {
  const auto aorta = open_tube({{0, 0, 100}, {0, 0, 40}}, 10.0);
  const auto iliac = open_tube({{0, 0, 45}, {0, 0, 35}, {15, 0, -20}}, 5.0);
  const geometry::Polyline device{{0, 0, 90}, {0, 0, 38}, {14, 0, -15}};
  const auto c = deform::measure_device_containment({{"aorta", &aorta}, {"iliac", &iliac}}, device);
  EXPECT_EQ(c.outside_length_mm, 0.0);
  EXPECT_TRUE(c.stretches.empty());
  // Without the iliac, the device below the aorta is past its opening, not outside.
  const auto alone = deform::measure_device_containment({{"aorta", &aorta}}, device);
  EXPECT_EQ(alone.outside_length_mm, 0.0);
  EXPECT_GT(alone.unjudged_length_mm, 40.0);
}

// Within the tolerance of the wall counts as inside; a step of 0 is refused.
TEST(DeviceContainment, GrazingTheWallIsInside) {
  // A closed box [0, 100]^3 (flat walls: no facets between the wire and the wall).
  geometry::TriangleMesh box;
  box.V.resize(8, 3);
  for (int i = 0; i < 8; ++i) box.V.row(i) << 100.0 * (i & 1), 100.0 * ((i >> 1) & 1), 100.0 * ((i >> 2) & 1);
  box.F.resize(12, 3);
  box.F << 0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5;
  const double x = 100.0 + 0.5 * deform::kOutsideToleranceMm;
  const auto grazing = deform::measure_device_containment({{"box", &box}}, {{x, 50, 10}, {x, 50, 90}});
  EXPECT_EQ(grazing.outside_length_mm, 0.0);
  const double y = 100.0 + 2.0 * deform::kOutsideToleranceMm;
  const auto beyond = deform::measure_device_containment({{"box", &box}}, {{50, y, 10}, {50, y, 90}});
  EXPECT_NEAR(beyond.outside_length_mm, 80.0, 1e-9);
  EXPECT_NEAR(beyond.outside_max_depth_mm, 2.0 * deform::kOutsideToleranceMm, 1e-9);
  EXPECT_FALSE(deform::leaves_device_outside(beyond));  // a tenth of a millimetre is not worth a warning
  EXPECT_THROW(deform::measure_device_containment({{"box", &box}}, {{x, 50, 10}, {x, 50, 90}}, 0.0), std::invalid_argument);
}

// A tube closed by caps where its segmentation stopped, the faces touching them marked (as
// the deformation marks those past its centerline's ends): the lumen is inside right up to
// the caps, a device on through a cap or out beside it there is past the vessel's end, not
// judged, and through the wall elsewhere it is outside.
TEST(DeviceContainment, CapsBoundTheLumenButWhatLiesPastThemIsNotJudged) {
  const auto tube = sim::tube_mesh({{0, 0, 0}, {0, 0, 100}}, [](double) { return 8.0; }, {32, 1.0, true});
  std::vector<char> caps(static_cast<std::size_t>(tube.F.rows()), 0);
  for (Eigen::Index f = 0; f < tube.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) caps[static_cast<std::size_t>(f)] |= tube.V(tube.F(f, k), 2) < 0.25 || tube.V(tube.F(f, k), 2) > 99.75;
  const auto measure = [&](const geometry::Polyline& device) {
    return deform::measure_device_containment({{"iliac", &tube, nullptr, caps}}, device);
  };
  // Up to 0.1 mm short of each cap, off the axis.
  const auto lumen = measure({{1, 0, 0.1}, {1, 0, 99.9}});
  EXPECT_EQ(lumen.outside_length_mm, 0.0);
  EXPECT_EQ(lumen.unjudged_length_mm, 0.0);
  // On through the far cap for 10 mm.
  const auto through = measure({{1, 0, 50}, {1, 0, 110}});
  EXPECT_EQ(through.outside_length_mm, 0.0);
  EXPECT_NEAR(through.unjudged_length_mm, 10.0, 0.5);
  // Out beside the cap, through the marked ring of wall next to it.
  const auto beside = measure({{0, 0, 50}, {0, 0, 99.9}, {10, 0, 99.9}});
  EXPECT_EQ(beside.outside_length_mm, 0.0);
  EXPECT_GT(beside.unjudged_length_mm, 1.5);
  // Through the wall in the middle: outside, as without caps.
  const auto wall = measure({{0, 0, 35}, {11, 0, 45}, {11, 0, 55}, {0, 0, 65}});
  ASSERT_EQ(wall.stretches.size(), 1u);
  EXPECT_NEAR(wall.outside_max_depth_mm, 3.0, 0.05);  // the 32-gon lies 0.04 mm inside the circle
  // The same tube unmarked is closed: past its cap the device is outside.
  const auto unmarked = deform::measure_device_containment({{"iliac", &tube}}, {{1, 0, 50}, {1, 0, 110}});
  EXPECT_NEAR(unmarked.outside_length_mm, 10.0, 0.5);
}
