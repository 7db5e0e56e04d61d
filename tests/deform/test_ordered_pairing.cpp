#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "evar/deform/control_points.hpp"
#include "ordered_pairing.hpp"
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
  // which runs along z) and its arc from the top (sliding), both held at the wire's end:
  // the wire reaches the vessel's end (the access), which holds the vessel's last sections.
  for (const auto& p : pairs) {
    const double height = geometry::point_at(cl, arc, p.section_arc_mm).z();
    EXPECT_NEAR(p.device_arc_mm, 0.5 * (std::min(height, 120.0) + std::min(p.section_arc_mm, 120.0)), 0.6)
        << p.section_arc_mm;
  }
  EXPECT_NEAR(pairs.back().section_arc_mm, arc.back(), 1e-9);
  EXPECT_NEAR(pairs.back().device_arc_mm, 120.0, 1e-6);
}

TEST(OrderedPairing, ADeviceLeavingTheFieldOfViewPairsAsTheWholeWireWould) {
  // The wire seen only down to z = 70 (the image's edge) continues straight to the access
  // at z = 120: every section whose partner lies on the part seen is paired as with the
  // whole wire, and the sections beyond are left without a partner, not crowded onto the
  // last point seen. (The whole wire ends at 110 here, short of the vessel's end by more
  // than a skeleton spacing, so that it is open as well: one reaching the end holds it.)
  const auto cl = winding_centerline(120.0, 15.0, 60.0);
  const auto whole = deform::ordered_pairing(cl, straight_device(0.0, 110.0), 0.5);
  const auto seen = deform::ordered_pairing(cl, straight_device(0.0, 70.0), 0.5);
  ASSERT_GT(seen.size(), 100u);
  ASSERT_GT(whole.size(), seen.size());
  for (std::size_t k = 0; k < seen.size(); ++k) {
    EXPECT_NEAR(seen[k].section_arc_mm, whole[k].section_arc_mm, 1e-9);
    EXPECT_NEAR(seen[k].device_arc_mm, whole[k].device_arc_mm, 1e-6);
  }
  EXPECT_LE(seen.back().device_arc_mm, 70.0 + 1e-9);
  EXPECT_GT(whole[seen.size()].device_arc_mm, 70.0);
  // Given from its far end, the same sections (device arcs counted from that end).
  const auto up = deform::ordered_pairing(cl, straight_device(70.0, 0.0), 0.5);
  ASSERT_EQ(up.size(), seen.size());
  for (std::size_t k = 0; k < seen.size(); ++k) {
    EXPECT_NEAR(up[up.size() - 1 - k].section_arc_mm, seen[k].section_arc_mm, 1e-9);
    EXPECT_NEAR(up[up.size() - 1 - k].device_arc_mm, 70.0 - seen[k].device_arc_mm, 1e-6);
  }
}

TEST(OrderedPairing, TheRunFromTheEntryFollowsTheDeviceHoweverFarItIsFromThePreoperativeCenterline) {
  // A vessel along +z from 0 to 60 mm entered at z = 0; the device comes from the aorta
  // (z < 0) and runs down 20 mm beside the preoperative centerline (a straightened iliac,
  // a moved pelvis) to z = 80, past the vessel's end.
  const auto cl = test::straight_centerline(60.0);
  geometry::Polyline device;
  for (int k = 0; k <= 240; ++k) device.emplace_back(20.0, 0.0, -40.0 + 0.5 * k);
  deform::ControlPointOptions options;  // 3 radii of 5 mm: nothing of it within reach
  EXPECT_TRUE(deform::device_points_in_vessel(cl, {{0.0, 60.0}, {5.0, 5.0}}, device, options).empty());
  const auto run = deform::device_run_from(cl, device, Eigen::Vector3d(0.0, 0.0, 0.0), 0.5);
  ASSERT_FALSE(run.empty());
  EXPECT_NEAR(run.front().z(), 0.0, 0.3);   // from the sample nearest the entry
  EXPECT_NEAR(run.back().z(), 60.0, 0.3);   // to the last whose foot is on the centerline
  for (std::size_t k = 1; k < run.size(); ++k) EXPECT_GT(run[k].z(), run[k - 1].z());
  // Given from the other end, the same run, still from the entry on.
  geometry::Polyline reversed(device.rbegin(), device.rend());
  const auto again = deform::device_run_from(cl, reversed, Eigen::Vector3d(0.0, 0.0, 0.0), 0.5);
  ASSERT_EQ(again.size(), run.size());
  for (std::size_t k = 0; k < run.size(); ++k) EXPECT_LT((again[k] - run[k]).norm(), 1e-9) << k;
  // Paired from the first section: the section at z with the run's point at z.
  const auto pairs = deform::ordered_pairing_from_entry(cl, run, 0.5);
  ASSERT_EQ(pairs.size(), 121u);
  EXPECT_DOUBLE_EQ(pairs.front().section_arc_mm, 0.0);
  for (const auto& p : pairs) EXPECT_NEAR(p.device_arc_mm, p.section_arc_mm - run.front().z(), 0.3);
  EXPECT_THROW(deform::device_run_from(cl, device, Eigen::Vector3d::Zero(), 0.0), std::invalid_argument);
  // A device seen only from z = 10 on (it enters the field of view below the junction)
  // does not pass the entry: no run, the pairing by the feet of what is within reach applies.
  const geometry::Polyline below(device.begin() + 100, device.end());
  EXPECT_TRUE(deform::device_run_from(cl, below, Eigen::Vector3d(0.0, 0.0, 0.0), 0.5).empty());
}

TEST(OrderedPairing, TheRunStartsWhereTheDeviceCrossesTheFirstSectionsPlane) {
  // A wire passing the junction (0, 0, 0) off-centre and at 45°: (5 + t, 0, t). Its point
  // nearest the junction, (2.5, 0, -2.5), lies above the first section; it crosses that
  // section's plane (z = 0) at (5, 0, 0), and that is the first section's partner.
  const auto cl = test::straight_centerline(60.0);
  geometry::Polyline device;
  for (int k = 0; k <= 200; ++k) device.emplace_back(5.0 + (-40.0 + 0.5 * k), 0.0, -40.0 + 0.5 * k);
  const auto run = deform::device_run_from(cl, device, Eigen::Vector3d::Zero(), 0.5);
  ASSERT_GE(run.size(), 2u);
  EXPECT_LT((run.front() - Eigen::Vector3d(5.0, 0.0, 0.0)).norm(), 1e-9);
  EXPECT_GT(run[1].z(), 0.0);
  const geometry::Polyline reversed(device.rbegin(), device.rend());
  const auto again = deform::device_run_from(cl, reversed, Eigen::Vector3d::Zero(), 0.5);
  ASSERT_EQ(again.size(), run.size());
  EXPECT_LT((again.front() - run.front()).norm(), 1e-9);
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
