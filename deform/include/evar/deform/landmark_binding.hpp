#pragma once
// Landmarks follow the surface they sit on: each is bound to its nearest triangle by
// barycentric coordinates plus its offset along the triangle normal, and re-evaluated on
// the deformed vertices.
#include <Eigen/Core>

#include "evar/geometry/triangle_mesh.hpp"

namespace evar::deform {

struct SurfaceBinding {
  int face = -1;
  Eigen::Vector3d barycentric = Eigen::Vector3d::Zero();
  double normal_offset_mm = 0.0;  ///< signed distance along the face normal
  double distance_mm = 0.0;       ///< distance to the surface when bound
};

SurfaceBinding bind_to_surface(const geometry::TriangleMesh& mesh, const Eigen::Vector3d& point);

/// Position of the bound point on the mesh with deformed vertices V (same faces).
Eigen::Vector3d evaluate_binding(const SurfaceBinding& binding, const geometry::Faces& F,
                                 const geometry::Vertices& V);

}  // namespace evar::deform
