#pragma once
// Closest point on a triangle mesh (exact, per triangle; Ericson's region test).
#include <Eigen/Core>
#include <vector>

#include "evar/geometry/triangle_mesh.hpp"

namespace evar::geometry {

struct SurfacePoint {
  int face = -1;
  Eigen::Vector3d barycentric;  ///< weights of F(face, 0..2)
  Eigen::Vector3d point;        ///< mm
  double distance_mm = 0.0;
};

/// Closest point of triangle (a, b, c) to p, as barycentric weights.
Eigen::Vector3d closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                          const Eigen::Vector3d& b, const Eigen::Vector3d& c);

/// Closest point of the whole mesh to p (a scan of the faces that can hold it; face -1 and
/// an infinite distance for a mesh without faces).
SurfacePoint closest_point_on_mesh(const TriangleMesh& mesh, const Eigen::Vector3d& p);

/// Closest points of the mesh to a cluster of points (e.g. one vessel's end): the same
/// answers as closest_point_on_mesh, with the faces that can hold any of them found in one
/// pass, so a few hundred queries cost about one scan of the mesh.
std::vector<SurfacePoint> closest_points_on_mesh(const TriangleMesh& mesh, const std::vector<Eigen::Vector3d>& points);

/// Index of the vertex nearest to p (linear scan).
int nearest_vertex(const geometry::Vertices& V,
                   const Eigen::Vector3d& p);

}  // namespace evar::geometry
