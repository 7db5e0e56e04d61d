#include "evar/deform/mesh_proxy.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include <Eigen/Geometry>
#include <meshoptimizer.h>

#include "evar/geometry/closest_point.hpp"

namespace evar::deform {

namespace {

// A face's frame: its first edge, the normal × edge, the normal (columns).
Eigen::Matrix3d face_frame(const geometry::Faces& F, const geometry::Vertices& V, int f) {
  const Eigen::Vector3d a = V.row(F(f, 0)).transpose(), b = V.row(F(f, 1)).transpose(), c = V.row(F(f, 2)).transpose();
  const Eigen::Vector3d e = (b - a).normalized(), n = (b - a).cross(c - a).normalized();
  Eigen::Matrix3d frame;
  frame << e, n.cross(e), n;
  return frame;
}

double surface_area(const geometry::TriangleMesh& m) {
  double a = 0.0;
  for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
    const Eigen::Vector3d p = m.V.row(m.F(f, 0)).transpose();
    a += 0.5 * (m.V.row(m.F(f, 1)).transpose() - p).cross(m.V.row(m.F(f, 2)).transpose() - p).norm();
  }
  return a;
}

// Triangles bucketed by their bounding boxes in a uniform grid, for nearest-triangle
// queries from points close to the surface (the fine vertices are within a fraction of an
// edge of it).
class TriangleGrid {
 public:
  TriangleGrid(const geometry::TriangleMesh& m, double cell) : m_(m), cell_(cell) {
    lo_ = m.V.colwise().minCoeff().transpose();
    for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
      Eigen::Vector3d a = m.V.row(m.F(f, 0)).transpose(), b = a;
      for (int j = 1; j < 3; ++j) {
        a = a.cwiseMin(m.V.row(m.F(f, j)).transpose());
        b = b.cwiseMax(m.V.row(m.F(f, j)).transpose());
      }
      const Eigen::Vector3i i0 = index(a), i1 = index(b);
      for (int x = i0.x(); x <= i1.x(); ++x)
        for (int y = i0.y(); y <= i1.y(); ++y)
          for (int z = i0.z(); z <= i1.z(); ++z) cells_[key({x, y, z})].push_back(static_cast<int>(f));
    }
  }

  // The closest point among the triangles in the 27 cells around p; exact whenever it is
  // within one cell of p (a closer triangle would reach into those cells), otherwise the
  // whole mesh is searched.
  geometry::SurfacePoint closest(const Eigen::Vector3d& p) const {
    geometry::SurfacePoint best;
    best.distance_mm = std::numeric_limits<double>::infinity();
    const Eigen::Vector3i c = index(p);
    for (int x = -1; x <= 1; ++x)
      for (int y = -1; y <= 1; ++y)
        for (int z = -1; z <= 1; ++z) {
          const auto it = cells_.find(key(c + Eigen::Vector3i(x, y, z)));
          if (it == cells_.end()) continue;
          for (const int f : it->second) {
            const Eigen::Vector3d a = m_.V.row(m_.F(f, 0)).transpose(), b = m_.V.row(m_.F(f, 1)).transpose(),
                                  cc = m_.V.row(m_.F(f, 2)).transpose();
            const Eigen::Vector3d w = geometry::closest_point_on_triangle(p, a, b, cc);
            const Eigen::Vector3d q = w[0] * a + w[1] * b + w[2] * cc;
            const double d = (q - p).norm();
            if (d < best.distance_mm) best = {f, w, q, d};
          }
        }
    if (best.distance_mm <= cell_) return best;
    return geometry::closest_point_on_mesh(m_, p);
  }

 private:
  Eigen::Vector3i index(const Eigen::Vector3d& p) const {
    return ((p - lo_) / cell_).array().floor().cast<int>();
  }
  static std::int64_t key(const Eigen::Vector3i& i) {
    return (static_cast<std::int64_t>(i.x() + (1 << 20)) << 42) | (static_cast<std::int64_t>(i.y() + (1 << 20)) << 21) |
           static_cast<std::int64_t>(i.z() + (1 << 20));
  }
  const geometry::TriangleMesh& m_;
  double cell_;
  Eigen::Vector3d lo_;
  std::unordered_map<std::int64_t, std::vector<int>> cells_;
};

}  // namespace

bool needs_proxy(const geometry::TriangleMesh& mesh, double proxy_edge_mm) {
  return proxy_edge_mm > 0.0 && geometry::median_edge_length(mesh) < 0.75 * proxy_edge_mm;
}

namespace {

// Quadric edge collapse of `fine` to about `target_vertices`, as a compact mesh whose
// vertices are fine ones; std::runtime_error when the result is not a valid mesh (closed
// when the fine mesh is).
geometry::TriangleMesh simplify(const geometry::TriangleMesh& fine, const std::vector<float>& positions,
                                const std::vector<unsigned>& indices, double target_vertices) {
  const auto n = static_cast<std::size_t>(fine.V.rows());
  std::vector<unsigned> simplified(indices.size());
  // A closed surface has about two triangles per vertex. The error bound is loose (5 % of
  // the mesh's extent): the vertex count is what we ask for, and the fine vertices'
  // distance to the result is measured by the caller.
  // The library asserts (aborts) on a target above the mesh's own count, which a mesh of
  // uneven triangles can ask for: its median edge is short while a few large faces hold
  // the area.
  const std::size_t target_indices = std::min(indices.size(), static_cast<std::size_t>(6.0 * target_vertices));
  const std::size_t count = meshopt_simplify(simplified.data(), indices.data(), indices.size(), positions.data(), n,
                                             3 * sizeof(float), target_indices, 0.05f, 0, nullptr);
  simplified.resize(count);
  // Where the simplifier pinches a thin part it can leave the same triangle twice, back to
  // back: a fin of no volume whose edge is shared by four faces. Both copies go, which
  // leaves the surface closed and every edge shared by two faces (checked below).
  std::map<std::array<unsigned, 3>, int> seen;
  const auto sorted = [&](std::size_t t) {
    std::array<unsigned, 3> k{simplified[3 * t], simplified[3 * t + 1], simplified[3 * t + 2]};
    std::sort(k.begin(), k.end());
    return k;
  };
  for (std::size_t t = 0; t < count / 3; ++t) ++seen[sorted(t)];
  std::vector<unsigned> faces;
  faces.reserve(count);
  for (std::size_t t = 0; t < count / 3; ++t)
    if (seen[sorted(t)] == 1)
      faces.insert(faces.end(), simplified.begin() + static_cast<std::ptrdiff_t>(3 * t),
                   simplified.begin() + static_cast<std::ptrdiff_t>(3 * t + 3));

  geometry::TriangleMesh coarse;
  std::vector<int> remap(n, -1);
  int kept = 0;
  for (const unsigned i : faces)
    if (remap[i] < 0) remap[i] = kept++;
  coarse.V.resize(kept, 3);
  for (std::size_t i = 0; i < n; ++i)
    if (remap[i] >= 0) coarse.V.row(remap[i]) = fine.V.row(static_cast<Eigen::Index>(i));
  coarse.F.resize(static_cast<Eigen::Index>(faces.size() / 3), 3);
  for (std::size_t t = 0; t < faces.size() / 3; ++t)
    for (int k = 0; k < 3; ++k) coarse.F(static_cast<Eigen::Index>(t), k) = remap[faces[3 * t + static_cast<std::size_t>(k)]];
  try {
    geometry::validate_mesh(coarse, "the proxy");
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("mesh proxy: ") + e.what());
  }
  if (geometry::is_closed(fine) && !geometry::is_closed(coarse))
    throw std::runtime_error("mesh proxy: the simplified mesh is not closed");
  return coarse;
}

}  // namespace

MeshProxy make_proxy(const geometry::TriangleMesh& fine, double edge_mm) {
  if (!(edge_mm > 0.0)) throw std::invalid_argument("mesh proxy: the edge length must be positive");
  const auto n = static_cast<std::size_t>(fine.V.rows());
  std::vector<float> positions(3 * n);
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) positions[3 * i + static_cast<std::size_t>(k)] = static_cast<float>(fine.V(static_cast<Eigen::Index>(i), k));
  std::vector<unsigned> indices(static_cast<std::size_t>(fine.F.size()));
  for (Eigen::Index f = 0; f < fine.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) indices[static_cast<std::size_t>(3 * f + k)] = static_cast<unsigned>(fine.F(f, k));
  // An equilateral triangulation with edges e has √3/2 e² of area per vertex.
  const double target_vertices = surface_area(fine) / (std::sqrt(3.0) / 2.0 * edge_mm * edge_mm);
  // Now and then the collapses pinch two sheets together along an edge (four faces, not a
  // fin); a slightly different target collapses other edges and usually avoids it.
  MeshProxy proxy;
  std::string why;
  for (const double factor : {1.0, 0.95, 1.05, 0.9, 1.1}) {
    ++proxy.attempts;
    try {
      proxy.coarse = simplify(fine, positions, indices, factor * target_vertices);
      why.clear();
      break;
    } catch (const std::runtime_error& e) {
      why = e.what();
    }
  }
  if (!why.empty()) throw std::runtime_error(why + " (at five targets around " + std::to_string(std::lround(target_vertices)) + " vertices)");

  const TriangleGrid grid(proxy.coarse, geometry::median_edge_length(proxy.coarse));
  proxy.bindings.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p = fine.V.row(static_cast<Eigen::Index>(i)).transpose();
    const geometry::SurfacePoint sp = grid.closest(p);
    ProxyBinding& b = proxy.bindings[i];
    b.face = sp.face;
    b.barycentric = sp.barycentric;
    b.offset_in_face = face_frame(proxy.coarse.F, proxy.coarse.V, sp.face).transpose() * (p - sp.point);
    proxy.largest_offset_mm = std::max(proxy.largest_offset_mm, sp.distance_mm);
  }
  return proxy;
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
