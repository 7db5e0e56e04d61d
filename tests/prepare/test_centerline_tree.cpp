// Centerline trees from what segmentation tools write: VMTK's paths, VMTK's branch pieces,
// Slicer's chained curves, all reduced to the same trunk and two branches.
#include <gtest/gtest.h>

#include <cmath>

#include "evar/base/input_error.hpp"
#include "evar/prepare/centerline_tree.hpp"
#include "support/error_message.hpp"

using namespace evar;
using geometry::CenterlineCurve;

namespace {

// Points every 0.5 mm from a to b (b included), radius r.
CenterlineCurve segment(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r) {
  CenterlineCurve c;
  const int n = static_cast<int>(std::ceil((b - a).norm() / 0.5));
  for (int k = 0; k <= n; ++k) c.points.push_back(a + (b - a) * k / n), c.radius_mm.push_back(r);
  return c;
}

CenterlineCurve joined(const CenterlineCurve& a, const CenterlineCurve& b) {
  CenterlineCurve c = a;
  c.points.insert(c.points.end(), b.points.begin() + 1, b.points.end());
  c.radius_mm.insert(c.radius_mm.end(), b.radius_mm.begin() + 1, b.radius_mm.end());
  return c;
}

const Eigen::Vector3d kInlet(0, 0, 100), kFork(0, 0, 40), kRight(-30, 0, -20), kLeft(30, 0, -20), kRenal(25, 0, 80);

void expect_the_tree(const prepare::BifurcationTree& t) {
  EXPECT_LT((t.trunk.front() - kInlet).norm(), 1e-9);
  EXPECT_LT((t.trunk.back() - kFork).norm(), 0.6);  // the last point the paths share, to a step
  EXPECT_EQ(t.trunk_radius_mm.size(), t.trunk.size());
  std::array<bool, 2> found{false, false};
  for (const auto& b : t.branches) {
    EXPECT_LT((b.front() - t.trunk.back()).norm(), 0.6);
    found[0] = found[0] || (b.back() - kRight).norm() < 1e-9;
    found[1] = found[1] || (b.back() - kLeft).norm() < 1e-9;
  }
  EXPECT_TRUE(found[0] && found[1]);
}

}  // namespace

TEST(CenterlineTree, VmtkPathsSharingTheirStartMakeTheTree) {
  const auto trunk = segment(kInlet, kFork, 10.0);
  const std::vector<CenterlineCurve> paths{joined(trunk, segment(kFork, kRight, 5.0)), joined(trunk, segment(kFork, kLeft, 5.0))};
  const auto t = prepare::bifurcation_tree(prepare::centerline_paths(paths, "c.vtp"), "c.vtp");
  expect_the_tree(t);
  EXPECT_EQ(t.note, "");
}

TEST(CenterlineTree, VmtkBranchPiecesAreJoinedByCenterlineAndTract) {
  // Path 0: trunk (tract 0) + right (tract 1); path 1: trunk + left, stored out of order.
  auto piece = [](CenterlineCurve c, long long id, long long tract) {
    c.cell_values = {{"CenterlineIds", id}, {"TractIds", tract}, {"GroupIds", tract == 0 ? 0 : id + 1}, {"Blanking", 0}};
    return c;
  };
  const std::vector<CenterlineCurve> pieces{piece(segment(kFork, kLeft, 5.0), 1, 1), piece(segment(kInlet, kFork, 10.0), 0, 0),
                                            piece(segment(kFork, kRight, 5.0), 0, 1), piece(segment(kInlet, kFork, 10.0), 1, 0)};
  const auto paths = prepare::centerline_paths(pieces, "b.vtp");
  ASSERT_EQ(paths.size(), 2u);
  expect_the_tree(prepare::bifurcation_tree(paths, "b.vtp"));
}

TEST(CenterlineTree, SlicerCurvesChainedEndToStartMakeTheTreeAndARenalStubIsLeftOut) {
  // The trunk in two curves, a renal stub branching off it, the two iliacs (no radii, as
  // markups have none).
  auto plain = [](CenterlineCurve c) {
    c.radius_mm.clear();
    return c;
  };
  const Eigen::Vector3d mid(0, 0, 80);
  const std::vector<CenterlineCurve> curves{plain(segment(kInlet, mid, 10)), plain(segment(mid, kFork, 10)),
                                            plain(segment(mid, kRenal, 3)), plain(segment(kFork, kRight, 5)),
                                            plain(segment(kFork, kLeft, 5))};
  const auto paths = prepare::centerline_paths(curves, "tree.mrk.json");
  ASSERT_EQ(paths.size(), 3u);  // to the renal outlet and both iliacs
  const auto t = prepare::bifurcation_tree(paths, "tree.mrk.json");
  EXPECT_LT((t.trunk.back() - kFork).norm(), 0.6);
  EXPECT_TRUE(t.trunk_radius_mm.empty());
  EXPECT_NE(t.note.find("of its 3 centerline paths, the two whose outlets lie farthest from the inlet"), std::string::npos)
      << t.note;
}

TEST(CenterlineTree, WhatMakesNoAortoIliacTreeIsRefusedByName) {
  const auto message = [](const std::vector<CenterlineCurve>& curves) {
    return test::error_message([&] { prepare::bifurcation_tree(prepare::centerline_paths(curves, "c.vtp"), "c.vtp"); });
  };
  EXPECT_NE(message({}).find("c.vtp: holds no curve"), std::string::npos);
  EXPECT_NE(message({segment(kInlet, kRight, 5)}).find("holds 1 centerline path; an aorto-iliac scene needs two"),
            std::string::npos);
  // Two separate trees.
  EXPECT_NE(message({segment(kInlet, kFork, 5), segment(kRight, kLeft, 5)}).find("make 2 separate trees"),
            std::string::npos);
  // Two paths that never part.
  const auto same = segment(kInlet, kRight, 5);
  EXPECT_NE(message({same, same}).find("never part"), std::string::npos) << message({same, same});
}

// Paths into side-branch stubs (a renal artery from the trunk, an internal iliac from an
// iliac) are side branches, each placed where it leaves its parent's lumen.
TEST(CenterlineTree, StubPathsAreSideBranchesLeavingTheirParentsLumen) {
  const Eigen::Vector3d renal_origin(0, 0, 80), internal_origin = kFork + 0.5 * (kRight - kFork);
  const auto trunk_to = [&](const Eigen::Vector3d& at) { return segment(kInlet, at, 10.0); };
  const auto right = segment(kFork, kRight, 5.0);
  std::vector<CenterlineCurve> paths{joined(trunk_to(kFork), right), joined(trunk_to(kFork), segment(kFork, kLeft, 5.0)),
                                     joined(trunk_to(renal_origin), segment(renal_origin, {40, 0, 78}, 3.0))};
  // The internal iliac: along the trunk and the right iliac to its origin, then off to the back.
  CenterlineCurve to_internal = trunk_to(kFork);
  for (const auto& p : segment(kFork, internal_origin, 5.0).points) to_internal.points.push_back(p), to_internal.radius_mm.push_back(5.0);
  to_internal = joined(to_internal, segment(internal_origin, internal_origin + Eigen::Vector3d(0, 25, -5), 2.5));
  paths.push_back(to_internal);
  const auto t = prepare::bifurcation_tree(prepare::centerline_paths(paths, "c.vtp"), "c.vtp");
  ASSERT_EQ(t.side_branches.size(), 2u);
  const auto& renal = t.side_branches[0].parent == -1 ? t.side_branches[0] : t.side_branches[1];
  const auto& internal = t.side_branches[0].parent == -1 ? t.side_branches[1] : t.side_branches[0];
  EXPECT_EQ(renal.parent, -1);
  EXPECT_NEAR(renal.leaves_parent.x(), 10.0, 0.6);  // the trunk's wall, 10 mm out
  EXPECT_LT((renal.outlet - Eigen::Vector3d(40, 0, 78)).norm(), 1e-9);
  const int right_branch = (t.branches[0].back() - kRight).norm() < 1e-9 ? 0 : 1;
  EXPECT_EQ(internal.parent, right_branch);
  EXPECT_NEAR((internal.leaves_parent - internal_origin).norm(), 5.0, 0.6);  // the iliac's wall, 5 mm out
}
