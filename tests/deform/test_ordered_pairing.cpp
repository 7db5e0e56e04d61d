#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "evar/deform/control_points.hpp"
#include "evar/deform/ordered_pairing.hpp"
#include "tube_fixture.hpp"

using namespace evar;

namespace {

// A tortuous vessel along +z: x = a sin(2π z / λ), sampled every millimetre.
geometry::Polyline winding_centerline(double length, double amplitude, double wavelength) {
  geometry::Polyline cl;
  for (int k = 0; k <= static_cast<int>(length); ++k)
    cl.emplace_back(amplitude * std::sin(2.0 * std::numbers::pi * k / wavelength), 0.0, k);
  return cl;
}

geometry::Polyline straight_device(double z0, double z1, double step = 0.5) {
  geometry::Polyline d;
  const int n = static_cast<int>(std::abs(z1 - z0) / step);
  for (int k = 0; k <= n; ++k) d.emplace_back(0.0, 0.0, z0 + (z1 > z0 ? 1.0 : -1.0) * k * step);
  return d;
}

}  // namespace

TEST(OrderedPairing, AlongAStraightVesselEachSectionPairsWithTheDevicePointBesideIt) {
  const auto cl = test::straight_centerline(60.0);
  const auto device = straight_device(5.0, 55.0);
  const auto pairs = deform::ordered_pairing(cl, device, 0.5);
  ASSERT_EQ(pairs.size(), 101u);  // sections every 0.5 mm from z = 5 to z = 55
  for (const auto& p : pairs) {
    // Shortest way and sliding agree: the section at z pairs with the device point at z.
    EXPECT_NEAR(p.device_arc_mm, p.section_arc_mm - 5.0, 1e-9);
  }
}

TEST(OrderedPairing, ADeviceGivenFromTheDistalEndPairsTheSameWay) {
  const auto cl = winding_centerline(120.0, 12.0, 60.0);
  const auto down = straight_device(2.0, 118.0), up = straight_device(118.0, 2.0);
  const auto a = deform::ordered_pairing(cl, down, 0.5), b = deform::ordered_pairing(cl, up, 0.5);
  ASSERT_FALSE(a.empty());
  ASSERT_EQ(a.size(), b.size());
  const double length = geometry::arc_lengths(down).back();
  // b runs from the distal end: its k-th pair is a's (n-1-k)-th, device arcs from the other end.
  for (std::size_t k = 0; k < a.size(); ++k) {
    const auto& q = b[b.size() - 1 - k];
    EXPECT_NEAR(a[k].section_arc_mm, q.section_arc_mm, 1e-9);
    EXPECT_NEAR(a[k].device_arc_mm, length - q.device_arc_mm, 1e-6);
  }
}

TEST(OrderedPairing, ATortuousVesselOnAStraightWireIsPairedInOrderBetweenShorteningAndSliding) {
  // 120 mm along z winding ±15 mm: its path is about 1.25 times the wire's.
  const auto cl = winding_centerline(120.0, 15.0, 60.0);
  const auto device = straight_device(0.0, 120.0);
  const auto pairs = deform::ordered_pairing(cl, device, 0.5);
  ASSERT_GT(pairs.size(), 200u);
  const auto arc = geometry::arc_lengths(cl);
  EXPECT_GT(arc.back(), 1.2 * 120.0);
  for (std::size_t k = 1; k < pairs.size(); ++k) {
    EXPECT_GT(pairs[k].section_arc_mm, pairs[k - 1].section_arc_mm);
    EXPECT_GE(pairs[k].device_arc_mm, pairs[k - 1].device_arc_mm);  // in order
  }
  EXPECT_NEAR(pairs.front().device_arc_mm, 0.0, 1e-6);
  EXPECT_LE(pairs.back().device_arc_mm, 120.0 + 1e-9);
  // Each partner is the mean of the section's own height (the shortest way onto the wire,
  // which runs along z) and its arc from the top, capped at the wire's length (sliding).
  for (const auto& p : pairs) {
    const double height = geometry::point_at(cl, arc, p.section_arc_mm).z();
    EXPECT_NEAR(p.device_arc_mm, 0.5 * (height + std::min(120.0, p.section_arc_mm)), 0.6) << p.section_arc_mm;
  }
}

TEST(OrderedPairing, ADeviceCrossingTheVesselIsLeftToTheNearestPairing) {
  const auto cl = test::straight_centerline(60.0);
  // Across the vessel at z = 30: every foot within a millimetre.
  geometry::Polyline device{{-20.0, 0.0, 30.0}, {20.0, 0.0, 30.5}};
  EXPECT_TRUE(deform::ordered_pairing(cl, device, 0.5).empty());
  EXPECT_THROW(deform::ordered_pairing(cl, device, 0.0), std::invalid_argument);
}

TEST(OrderedPairing, HandlesOfAWindingTubeOnAStraightWireFollowTheWireInOrder) {
  // A tortuous iliac-sized tube (radius 5 mm) winding ±15 mm, a straight wire down its axis
  // of symmetry: with nearest rays a loop is pushed toward where the wire passes a
  // crossing; paired in order, each handle's device point lies further along the wire the
  // further along the vessel its section is.
  const auto cl = winding_centerline(120.0, 15.0, 60.0);
  const auto mesh = sim::tube_mesh(cl, [](double) { return 5.0; }, {24, 1.5, true});
  const geometry::RayCaster caster(mesh);
  const auto radius = deform::radius_profile(deform::build_skeleton(caster, cl));
  const auto device = straight_device(1.0, 119.0);
  deform::ControlPointOptions options;
  options.pair_in_order = true;
  options.reach_radii = 5.0;  // the loops' apexes lie 15 mm (3 radii) from the wire
  const auto handles = deform::select_control_points(mesh, caster, cl, radius, device, options);
  ASSERT_GT(handles.size(), 20u);
  // Sorted by section arc: device heights non-decreasing (a handle from a device sample and
  // one from its section may share a height).
  for (std::size_t k = 1; k < handles.size(); ++k)
    EXPECT_GE(handles[k].device_point.z(), handles[k - 1].device_point.z() - 0.5) << k;
  // The apex sections (centre |x| = 15 mm, their wall facing the wire at 10 mm) have
  // handles pulling them onto it.
  int apex = 0;
  for (const auto& h : handles) apex += std::abs(h.hit.x()) > 8.0;
  EXPECT_GT(apex, 4);
}

TEST(OrderedPairing, TheInverseFindsTheSectionOfAPartnerFromEitherEnd) {
  const std::vector<deform::SectionPartner> pairs{{10.0, 0.0}, {11.0, 2.0}, {12.0, 2.0}, {13.0, 2.0}, {14.0, 6.0}};
  EXPECT_DOUBLE_EQ(deform::section_arc_of(pairs, -1.0), 10.0);
  EXPECT_DOUBLE_EQ(deform::section_arc_of(pairs, 1.0), 10.5);  // between the first two
  EXPECT_DOUBLE_EQ(deform::section_arc_of(pairs, 2.0), 12.0);  // the middle of the run sharing it
  EXPECT_DOUBLE_EQ(deform::section_arc_of(pairs, 5.0), 13.75);
  EXPECT_DOUBLE_EQ(deform::section_arc_of(pairs, 9.0), 14.0);
  EXPECT_THROW(deform::section_arc_of({}, 1.0), std::invalid_argument);
}
