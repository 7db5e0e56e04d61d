#pragma once
// One aorto-iliac surface cut into the vessels a scene deforms one by one: each iliac from
// a plane square to its centerline just below where its lumen has parted from the other
// iliac's, the rest (the aorta down to the crotch) the aorta. The pieces share the cut's
// vertices, so an iliac's top ring lies on the aortic rim it is bound to.
#include <Eigen/Core>
#include <array>
#include <string>

#include "evar/geometry/ray_caster.hpp"
#include "evar/geometry/triangle_mesh.hpp"
#include "evar/prepare/centerline_tree.hpp"

namespace evar::prepare {

struct SurfacePieces {
  geometry::TriangleMesh aorta;
  std::array<geometry::TriangleMesh, 2> iliacs;  ///< along tree.branches[0] and [1]
  std::array<double, 2> cut_arc_mm{};            ///< along each branch, where its piece begins
  std::array<Eigen::Vector3d, 2> cut_centre;     ///< on the branch's centerline
  std::array<Eigen::Vector3d, 2> cut_normal;     ///< the branch's direction there (distal)
};

/// Lumen radius per point of `centerline` from the surface (its BVH: distance to the nearest
/// wall), for centerlines that come without one.
std::vector<double> radius_from_surface(const geometry::RayCaster& surface, const geometry::Polyline& centerline);

/// Cuts `surface` (LPS, one connected surface; `caster` built over it; `tree` with radii, in
/// the same frame).
/// base::InputError naming `source` when a branch's lumen never parts from the other's,
/// or a cut does not separate the branch (the piece would take most of the surface).
SurfacePieces split_surface(const geometry::TriangleMesh& surface, const geometry::RayCaster& caster,
                            const BifurcationTree& tree, const std::string& source);

}  // namespace evar::prepare
