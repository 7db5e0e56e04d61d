#pragma once
// Moving a swept tube with its centerline, section by section: each point near the
// centerline moves with the place it projects to (linear between points), translated, or
// also turned by a share of the least rotation taking the section's old tangent to its new
// one. Both ground-truth models move their meshes and landmarks this way.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "evar/geometry/polyline.hpp"
#include "evar/geometry/triangle_mesh.hpp"

namespace evar::sim::detail {

/// Unit tangents at the points (central differences, one-sided at the ends).
std::vector<Eigen::Vector3d> point_tangents(const geometry::Polyline& c);

class SectionSweep {
 public:
  /// Sections translate only: they stay in planes parallel to the old ones, and the map
  /// folds only where the centerline is compressed along itself by more than its length.
  SectionSweep(const geometry::Polyline& from, const geometry::Polyline& to);
  /// Sections also turn, point i by `turn[i]` (0 to 1) of its tangent's turn. Throws
  /// std::invalid_argument unless from, to and turn have the same (>= 2) points.
  SectionSweep(const geometry::Polyline& from, const geometry::Polyline& to, const std::vector<double>& turn);

  /// Where `x` goes; `hint` carries the segment of the previous query (start with -1).
  Eigen::Vector3d map(const Eigen::Vector3d& x, int* hint) const;
  /// Every vertex of `mesh` mapped (faces kept).
  geometry::TriangleMesh map(const geometry::TriangleMesh& mesh) const;

 private:
  const geometry::Polyline& from_;
  const geometry::Polyline& to_;
  geometry::PolylineProjector projector_;
  std::vector<double> arc_;
  std::vector<Eigen::Quaterniond> turn_;  ///< per point; empty when sections only translate
};

}  // namespace evar::sim::detail
