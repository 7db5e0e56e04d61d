#include "evar/deform/mesh_proxy.hpp"

#include "evar/geometry/ray_caster.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>

#include "evar/geometry/closest_point.hpp"
#include "evar/base/quantity_text.hpp"
#include "isotropic_remesh.hpp"

namespace evar::deform {

namespace {

// How far (in proxy edges) a fine vertex may lie from the proxy.
constexpr double kLargestOffsetInEdges = 1.5;

// A face's frame: its first edge, the normal × edge, the normal (columns).
Eigen::Matrix3d face_frame(const geometry::Faces& F, const geometry::Vertices& V, int f) {
  const Eigen::Vector3d a = V.row(F(f, 0)).transpose(), b = V.row(F(f, 1)).transpose(), c = V.row(F(f, 2)).transpose();
  const Eigen::Vector3d e = (b - a).normalized(), n = (b - a).cross(c - a).normalized();
  Eigen::Matrix3d frame;
  frame << e, n.cross(e), n;
  return frame;
}

// Twice the face's area along its normal.
Eigen::Vector3d area_normal(const geometry::TriangleMesh& m, Eigen::Index f) {
  const Eigen::Vector3d a = m.V.row(m.F(f, 0)).transpose();
  return (m.V.row(m.F(f, 1)).transpose() - a).cross(m.V.row(m.F(f, 2)).transpose() - a);
}

// The surface's normal direction at each vertex at about the scale of `scale_mm`: the
// area-weighted face normals round it, then averaged with the neighbours' until the
// averaging has reached that far (a segmentation's voxel staircase has facets turned far
// from the surface it approximates, some against it).
std::vector<Eigen::Vector3d> smoothed_vertex_normals(const geometry::TriangleMesh& m, double scale_mm) {
  const auto n = static_cast<std::size_t>(m.V.rows());
  std::vector<Eigen::Vector3d> normal(n, Eigen::Vector3d::Zero());
  std::vector<std::vector<int>> next(n);
  for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
    const Eigen::Vector3d a = area_normal(m, f);
    for (int k = 0; k < 3; ++k) {
      normal[static_cast<std::size_t>(m.F(f, k))] += a;
      next[static_cast<std::size_t>(m.F(f, k))].push_back(m.F(f, (k + 1) % 3));
    }
  }
  const double edge = std::max(geometry::median_edge_length(m), 1e-6);
  const int passes = std::clamp(static_cast<int>(std::ceil(scale_mm / edge)), 1, 8);
  for (int pass = 0; pass < passes; ++pass) {
    std::vector<Eigen::Vector3d> averaged = normal;
    for (std::size_t i = 0; i < n; ++i)
      for (const int j : next[i]) averaged[i] += normal[static_cast<std::size_t>(j)];
    normal = std::move(averaged);
  }
  return normal;
}

}  // namespace

double sliver_fraction(const geometry::TriangleMesh& mesh) {
  if (mesh.F.rows() == 0) return 0.0;
  // An angle over 150 degrees: cos < -cos(30°). Faces of no area are no slivers (no shape).
  const double cos_limit = -std::sqrt(3.0) / 2.0;
  Eigen::Index slivers = 0;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = mesh.V.row(mesh.F(f, k)).transpose();
      const Eigen::Vector3d u = mesh.V.row(mesh.F(f, (k + 1) % 3)).transpose() - p;
      const Eigen::Vector3d w = mesh.V.row(mesh.F(f, (k + 2) % 3)).transpose() - p;
      const double lengths = u.norm() * w.norm();
      if (lengths > 0.0 && u.cross(w).norm() > 0.0 && u.dot(w) < cos_limit * lengths) {
        ++slivers;
        break;
      }
    }
  return static_cast<double>(slivers) / static_cast<double>(mesh.F.rows());
}

bool needs_proxy(const geometry::TriangleMesh& mesh, double proxy_edge_mm) {
  return proxy_edge_mm > 0.0 &&
         (geometry::median_edge_length(mesh) < 0.75 * proxy_edge_mm || sliver_fraction(mesh) > kSliverFractionForProxy);
}

MeshProxy make_proxy(const geometry::TriangleMesh& fine, double edge_mm) {
  if (!(edge_mm > 0.0)) throw std::invalid_argument("mesh proxy: the edge length must be positive");
  if (fine.F.rows() == 0) throw std::runtime_error("mesh proxy: the mesh has no faces");
  const auto n = static_cast<std::size_t>(fine.V.rows());
  MeshProxy proxy;
  proxy.edge_mm = edge_mm;
  // One BVH over the fine surface: the remesher puts its vertices back on it, and the check
  // below looks up where each face lies.
  const geometry::RayCaster fine_bvh(fine, geometry::RayCaster::BuildQuality::Low);
  proxy.coarse = detail::isotropic_remesh(fine, fine_bvh, edge_mm);
  try {
    geometry::validate_mesh(proxy.coarse, "the proxy");
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("mesh proxy: ") + e.what());
  }
  if (geometry::is_closed(fine) && !geometry::is_closed(proxy.coarse))
    throw std::runtime_error("mesh proxy: the remeshed surface is not closed");
  // The same surface, face by face: each has area and faces the way the fine surface does
  // where it lies, at the scale of a proxy edge (a vessel thinner than about an edge can
  // fold or shrink under the collapses; then the fine mesh is solved as it is).
  const auto fine_normal = smoothed_vertex_normals(fine, edge_mm);
  for (Eigen::Index f = 0; f < proxy.coarse.F.rows(); ++f) {
    const Eigen::Vector3d normal = area_normal(proxy.coarse, f);
    if (!(0.5 * normal.norm() > 1e-3 * edge_mm * edge_mm))
      throw std::runtime_error("mesh proxy: face " + std::to_string(f) + " of the remeshed surface has no area");
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) centroid += proxy.coarse.V.row(proxy.coarse.F(f, k)).transpose() / 3.0;
    const auto on_fine = fine_bvh.closest_point(centroid);
    Eigen::Vector3d there = Eigen::Vector3d::Zero();
    if (on_fine)
      for (int k = 0; k < 3; ++k)
        there += on_fine->barycentric[k] * fine_normal[static_cast<std::size_t>(fine.F(on_fine->face, k))];
    if (!on_fine || !(normal.dot(there) > 0.0))
      throw std::runtime_error("mesh proxy: face " + std::to_string(f) + " of the remeshed surface, at (" +
                               base::quantity_text(centroid.x(), "", 1) + ", " + base::quantity_text(centroid.y(), "", 1) +
                               ", " + base::quantity_text(centroid.z(), "", 1) +
                               ") mm, is turned against the mesh (a vessel thinner than the proxy's edge?)");
  }

  const geometry::RayCaster coarse_bvh(proxy.coarse, geometry::RayCaster::BuildQuality::Low);
  proxy.bindings.resize(n);
  Eigen::Vector3d farthest = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p = fine.V.row(static_cast<Eigen::Index>(i)).transpose();
    const auto found = coarse_bvh.closest_point(p);
    if (!found) throw std::runtime_error("mesh proxy: the remeshed surface has no faces");
    const geometry::SurfacePoint& sp = *found;
    ProxyBinding& b = proxy.bindings[i];
    b.face = sp.face;
    b.barycentric = sp.barycentric;
    b.offset_in_face = face_frame(proxy.coarse.F, proxy.coarse.V, sp.face).transpose() * (p - sp.point);
    if (sp.distance_mm > proxy.largest_offset_mm) proxy.largest_offset_mm = sp.distance_mm, farthest = p;
  }
  // A convex crease (a flat cap's rim) is rounded by about half an edge; a sharp concave one
  // (a segmentation's crotch at a bifurcation) is bridged by faces up to about an edge above
  // its floor; a fine vertex farther away than one and a half edges means the proxy lost part
  // of the surface (a thin vessel shrunk along its length).
  if (proxy.largest_offset_mm > kLargestOffsetInEdges * edge_mm)
    throw std::runtime_error("mesh proxy: a vertex of the mesh, at (" + base::quantity_text(farthest.x(), "", 1) + ", " +
                             base::quantity_text(farthest.y(), "", 1) + ", " + base::quantity_text(farthest.z(), "", 1) +
                             ") mm, lies " + base::quantity_text(proxy.largest_offset_mm, "mm") +
                             " from the remeshed surface, more than 1.5 times its edge of " + base::quantity_text(edge_mm, "mm") +
                             " (a vessel thinner than the proxy's edge?)");
  return proxy;
}

MeshProxy make_proxy_or_finer(const geometry::TriangleMesh& fine, double edge_mm) {
  const double median_edge = geometry::median_edge_length(fine);
  std::string reasons;
  double edge = edge_mm;
  for (int rung = 0; rung < 3; ++rung, edge *= 0.8) {
    if (rung > 0 && !(edge > median_edge)) break;
    try {
      return make_proxy(fine, edge);
    } catch (const std::runtime_error& e) {
      reasons += (reasons.empty() ? "" : "; at ") + std::string(rung == 0 ? "" : base::quantity_text(edge, "mm", 2) + ": ") + e.what();
    }
  }
  throw std::runtime_error(reasons);
}

geometry::Vertices follow_proxy(const MeshProxy& proxy, const geometry::Vertices& V) {
  geometry::Vertices out(static_cast<Eigen::Index>(proxy.bindings.size()), 3);
  for (std::size_t i = 0; i < proxy.bindings.size(); ++i) {
    const ProxyBinding& b = proxy.bindings[i];
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    for (int j = 0; j < 3; ++j) q += b.barycentric[j] * V.row(proxy.coarse.F(b.face, j)).transpose();
    out.row(static_cast<Eigen::Index>(i)) = (q + face_frame(proxy.coarse.F, V, b.face) * b.offset_in_face).transpose();
  }
  return out;
}

}  // namespace evar::deform
