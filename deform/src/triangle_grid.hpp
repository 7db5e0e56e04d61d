#pragma once
// Nearest-triangle queries for points close to a surface (a fraction of an edge away):
// triangles bucketed by their bounding boxes in a uniform grid.
#include <cstdint>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "evar/geometry/closest_point.hpp"
#include "evar/geometry/triangle_mesh.hpp"

namespace evar::deform::detail {

class TriangleGrid {
 public:
  /// The mesh must outlive the grid and keep its vertices while it is queried.
  TriangleGrid(const geometry::TriangleMesh& m, double cell_mm);

  /// The closest point among the triangles in the 27 cells around p; exact whenever it is
  /// within one cell of p (a closer triangle would reach into those cells), otherwise the
  /// whole mesh is searched.
  geometry::SurfacePoint closest(const Eigen::Vector3d& p) const;

 private:
  Eigen::Vector3i index(const Eigen::Vector3d& p) const;
  static std::int64_t key(const Eigen::Vector3i& i);

  const geometry::TriangleMesh& m_;
  double cell_;
  Eigen::Vector3d lo_;
  std::unordered_map<std::int64_t, std::vector<int>> cells_;
};

}  // namespace evar::deform::detail
