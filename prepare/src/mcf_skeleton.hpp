#pragma once
// CGAL's mean-curvature-flow skeleton (Tagliasacchi et al. 2012) of a closed triangle
// mesh, as a plain graph: the only file of evarnode that sees CGAL.
#include <Eigen/Core>
#include <utility>
#include <vector>

#include "evar/geometry/triangle_mesh.hpp"

namespace evar::prepare {

struct SkeletonGraph {
  std::vector<Eigen::Vector3d> points;          ///< mm, in the mesh's frame
  std::vector<std::pair<int, int>> edges;       ///< indices into points
  std::vector<std::vector<int>> mesh_vertices;  ///< per point: the mesh vertices that collapsed onto it
  int holes_closed = 0;                         ///< openings triangulated over before the flow
};

/// The medially centred skeleton of `mesh`, which must be two-manifold and consistently
/// wound (std::invalid_argument naming the first face that is not). Openings (a surface
/// cut open at its vessel ends) are closed by triangles over their rims first, on a copy.
SkeletonGraph mean_curvature_flow_skeleton(const geometry::TriangleMesh& mesh);

}  // namespace evar::prepare
