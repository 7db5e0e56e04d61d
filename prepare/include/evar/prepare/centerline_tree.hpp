#pragma once
// An aorto-iliac centerline tree from what segmentation tools write: VMTK's centerline
// paths (one per outlet, each from the inlet), VMTK's branch pieces (CenterlineIds and
// TractIds cells), or curves chained end to start (3D Slicer's centerline trees), reduced
// to the aortic trunk and the two iliac branches.
#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "evar/geometry/centerline_file.hpp"
#include "evar/geometry/polyline.hpp"

namespace evar::prepare {

/// The inlet-to-outlet paths the curves make. Curves that all start at one point are paths
/// already; VMTK branch pieces are joined by CenterlineIds in TractIds order; otherwise a
/// curve that starts within 1.5 mm of another's end continues it, and every path runs from
/// the one curve nothing continues to a curve nothing continues from. base::InputError
/// naming `source` when they make no tree (no curve, several roots, a loop).
std::vector<geometry::CenterlineCurve> centerline_paths(const std::vector<geometry::CenterlineCurve>& curves,
                                                       const std::string& source);

/// A path other than the two iliacs: a side branch (renal, mesenteric, internal iliac) of
/// the trunk or of an iliac.
struct SideBranch {
  int parent = -1;  ///< -1: the trunk; 0 or 1: that iliac branch
  /// Its centerline where it leaves the parent's lumen (the parent's radius from the
  /// parent's centerline; the parting point when the parent has no radii): next to its
  /// ostium.
  Eigen::Vector3d leaves_parent = Eigen::Vector3d::Zero();
  Eigen::Vector3d outlet = Eigen::Vector3d::Zero();  ///< its far end
};

struct BifurcationTree {
  /// From the inlet to the point where the iliac paths part (where they first lie more
  /// than 0.5 mm apart), and from there to each outlet; radii (mm) per point where the
  /// source had them, else empty.
  geometry::Polyline trunk;
  std::vector<double> trunk_radius_mm;
  std::array<geometry::Polyline, 2> branches;
  std::array<std::vector<double>, 2> branch_radius_mm;
  /// The other paths, each from where it parts from the trunk or an iliac.
  std::vector<SideBranch> side_branches;
  /// Which paths were taken when there were more than two (the two whose outlets lie
  /// farthest from the inlet: the iliacs, not a renal or lumbar stub); "" otherwise.
  std::string note;
};

/// The tree of the two paths whose outlets lie farthest from the inlet. base::InputError
/// naming `source` for fewer than two paths, or two that never part.
BifurcationTree bifurcation_tree(const std::vector<geometry::CenterlineCurve>& paths, const std::string& source);

}  // namespace evar::prepare
