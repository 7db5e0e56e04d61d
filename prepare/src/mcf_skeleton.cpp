#include "mcf_skeleton.hpp"

#include <CGAL/Mean_curvature_flow_skeletonization.h>
#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <functional>
#include <stdexcept>
#include <type_traits>

namespace evar::prepare::detail {
// The flow's traits: CGAL's Cartesian kernel under a name of our own, so that the ordering
// below applies to the flow's meso-skeleton and to nothing else.
struct SkeletonTraits : CGAL::Simple_cartesian<double> {};
using SurfaceMesh = CGAL::Surface_mesh<SkeletonTraits::Point_3>;
using Skeletonization = CGAL::Mean_curvature_flow_skeletonization<SurfaceMesh, SkeletonTraits>;
// The meso-skeleton the flow contracts (a Polyhedron_3, CGAL's own choice) and its edges.
using MesoSkeleton = CGAL::Polyhedron_3<SkeletonTraits, CGAL::internal::Skel_polyhedron_items_3<SurfaceMesh::Vertex_index>>;
using MesoEdge = boost::graph_traits<MesoSkeleton>::edge_descriptor;
// Should CGAL change its meso-skeleton's type, the ordering below would silently stop
// applying: refuse to build instead.
static_assert(std::is_same_v<MesoSkeleton, Skeletonization::Meso_skeleton>,
              "CGAL's meso-skeleton type changed: update MesoSkeleton so its edges are ordered by id");
}  // namespace evar::prepare::detail

// The flow collapses short edges in the order of a std::set of edges, which CGAL orders by
// the halfedges' heap addresses: the skeleton then differs from run to run, even within one
// process. Ordered by the halfedges' ids instead (unique and unchanged while the collapses
// run: the flow numbers every halfedge afresh before each collapse pass), the skeleton is the
// same for the same surface.
template <>
struct std::less<evar::prepare::detail::MesoEdge> {
  bool operator()(const evar::prepare::detail::MesoEdge& a, const evar::prepare::detail::MesoEdge& b) const {
    return key(a) < key(b);
  }
  static std::size_t key(const evar::prepare::detail::MesoEdge& e) {
    return std::min(e.halfedge()->id(), e.halfedge()->opposite()->id());
  }
};

namespace evar::prepare {
namespace {
using detail::SkeletonTraits;
using detail::SurfaceMesh;
using detail::Skeletonization;
}  // namespace

SkeletonGraph mean_curvature_flow_skeleton(const geometry::TriangleMesh& mesh) {
  SurfaceMesh surface;
  std::vector<SurfaceMesh::Vertex_index> vertex(static_cast<std::size_t>(mesh.V.rows()));
  for (Eigen::Index i = 0; i < mesh.V.rows(); ++i)
    vertex[static_cast<std::size_t>(i)] = surface.add_vertex({mesh.V(i, 0), mesh.V(i, 1), mesh.V(i, 2)});
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    const auto face = surface.add_face(vertex[static_cast<std::size_t>(mesh.F(f, 0))],
                                       vertex[static_cast<std::size_t>(mesh.F(f, 1))],
                                       vertex[static_cast<std::size_t>(mesh.F(f, 2))]);
    if (face == SurfaceMesh::null_face())
      throw std::invalid_argument("face " + std::to_string(f) + " breaks the surface's manifoldness or winding");
  }
  SkeletonGraph graph;
  if (!CGAL::is_closed(surface)) {
    std::vector<SurfaceMesh::Halfedge_index> rims;
    CGAL::Polygon_mesh_processing::extract_boundary_cycles(surface, std::back_inserter(rims));
    for (const auto rim : rims) {
      std::vector<SurfaceMesh::Face_index> patch;
      CGAL::Polygon_mesh_processing::triangulate_hole(surface, rim, std::back_inserter(patch));
      if (patch.empty()) throw std::invalid_argument("an opening of the surface could not be closed by triangles");
      ++graph.holes_closed;
    }
  }

  // Faces wound outward: the flow's medial poles lie on the side opposite the normals.
  if (CGAL::Polygon_mesh_processing::volume(surface) < 0.0)
    CGAL::Polygon_mesh_processing::reverse_face_orientations(surface);

  Skeletonization::Skeleton skeleton;
  Skeletonization flow(surface);
  flow(skeleton);

  const auto n = boost::num_vertices(skeleton);
  graph.points.resize(n);
  graph.mesh_vertices.resize(n);
  for (const auto v : CGAL::make_range(boost::vertices(skeleton))) {
    const auto& p = skeleton[v].point;
    graph.points[v] = {p.x(), p.y(), p.z()};
    for (const auto mv : skeleton[v].vertices) graph.mesh_vertices[v].push_back(static_cast<int>(mv.idx()));
  }
  for (const auto e : CGAL::make_range(boost::edges(skeleton)))
    graph.edges.emplace_back(static_cast<int>(boost::source(e, skeleton)), static_cast<int>(boost::target(e, skeleton)));
  return graph;
}

}  // namespace evar::prepare
