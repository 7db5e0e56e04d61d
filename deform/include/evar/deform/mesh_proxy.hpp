#pragma once
// A coarser stand-in for a vessel mesh much finer than the deformation needs. ARAP's
// membrane energy on a fine mesh has crumpled low-energy states that a coarse one cannot
// reach, and the cost grows faster than the vertex count (docs/DEFORMATION.md); so such a
// vessel is solved on a proxy of about the paper's resolution and the fine mesh follows
// it: each fine vertex is bound to the proxy's nearest triangle (barycentric weights plus
// its offset in that triangle's frame) and re-evaluated on the deformed proxy.
#include <vector>

#include <Eigen/Core>

#include "evar/geometry/triangle_mesh.hpp"

namespace evar::deform {

/// A fine vertex on the proxy: its closest point there (face, barycentric weights) and
/// what remains, in that face's own frame (first edge, normal × edge, normal), so the
/// vertex turns with the face and an unmoved or rigidly moved proxy gives it back exactly.
struct ProxyBinding {
  int face = -1;
  Eigen::Vector3d barycentric = Eigen::Vector3d::Zero();
  Eigen::Vector3d offset_in_face = Eigen::Vector3d::Zero();  ///< mm
};

struct MeshProxy {
  geometry::TriangleMesh coarse;          ///< closed if the fine mesh is; its vertices lie on the fine surface
  std::vector<ProxyBinding> bindings;     ///< per fine vertex, on `coarse`
  double largest_offset_mm = 0.0;         ///< of any fine vertex from the proxy surface
  double edge_mm = 0.0;                   ///< the edge length it was remeshed to
};

/// The share of a mesh's faces that are slivers: an angle over 150 degrees, where the
/// cotangent weight of the opposite edge is below −√3 and ARAP's membrane energy loses its
/// hold on the face's shape (it can be turned over by a deformation that bends its
/// neighbours only a little). Marching cubes leaves them by the hundreds (0.5-2 % of the
/// faces on the segmentation phantom, 1.7 % on VMTK's surface); the simulator's meshes have
/// none.
double sliver_fraction(const geometry::TriangleMesh& mesh);

/// More slivers than this share of the faces: the mesh is solved on a proxy whatever its
/// edge length (one in a thousand lets a stray sliver from an export's rounding pass).
inline constexpr double kSliverFractionForProxy = 1e-3;

/// Whether a mesh is solved on a proxy with edges of about `proxy_edge_mm`: when its
/// median edge is under 3/4 of that, or it carries slivers (above); never when
/// `proxy_edge_mm` is 0.
bool needs_proxy(const geometry::TriangleMesh& mesh, double proxy_edge_mm);

/// Isotropic remeshing of the fine surface (Botsch & Kobbelt 2004) to near-equilateral
/// triangles with edges of about `edge_mm`, keeping the topology; then every fine vertex
/// bound to it. A sharp convex crease (a flat cap's rim) is rounded by up to about half an
/// edge, a sharp concave one (a crotch) bridged up to about an edge above its floor;
/// the fine vertices keep their offsets, so the output keeps it. The rim of an open mesh
/// keeps a subset of its vertices. std::runtime_error when the result is not a valid mesh (the
/// caller then solves the fine mesh itself).
MeshProxy make_proxy(const geometry::TriangleMesh& fine, double edge_mm);

/// make_proxy at `edge_mm`, or, where that is refused (a side-branch stub or a vessel
/// thinner than about an edge folds under the collapses), at finer edges: each rung 4/5 of
/// the last, at most two, and only while still longer than the mesh's median edge (a proxy
/// no coarser than its mesh would gain nothing). A finer proxy costs more per solve than
/// the asked one, but unlike a segmentation's own mesh it has no slivers to turn over and
/// even triangles (docs/DEFORMATION.md). std::runtime_error with every rung's reason
/// when none holds (the caller then solves the fine mesh itself).
MeshProxy make_proxy_or_finer(const geometry::TriangleMesh& fine, double edge_mm);

/// The fine mesh's vertices for the proxy's vertices V (same order as proxy.coarse.V).
geometry::Vertices follow_proxy(const MeshProxy& proxy, const geometry::Vertices& V);

}  // namespace evar::deform
