// Mesh checks at the input edge: what the deformation and ray casting rely on.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "evar/base/input_error.hpp"
#include "evar/geometry/triangle_mesh.hpp"

namespace evar::geometry {

namespace {

[[noreturn]] void reject(std::string_view source, const std::string& what) {
  throw base::InputError(std::string(source) + ": " + what);
}

std::uint64_t edge_key(int a, int b) {
  const auto lo = static_cast<std::uint64_t>(static_cast<std::uint32_t>(std::min(a, b)));
  const auto hi = static_cast<std::uint64_t>(static_cast<std::uint32_t>(std::max(a, b)));
  return (lo << 32) | hi;
}

// Only runs when the edge is already known to be bad, so a linear scan is fine.
std::string faces_using_edge(const Faces& F, int a, int b) {
  std::ostringstream out;
  int listed = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    bool has_a = false, has_b = false;
    for (int k = 0; k < 3; ++k) {
      has_a = has_a || F(f, k) == a;
      has_b = has_b || F(f, k) == b;
    }
    if (!(has_a && has_b)) continue;
    if (listed == 5) {
      out << ", ...";
      break;
    }
    out << (listed++ ? ", " : "") << f;
  }
  return out.str();
}

}  // namespace

void validate_mesh(const TriangleMesh& mesh, std::string_view source) {
  const auto& V = mesh.V;
  const auto& F = mesh.F;
  if (F.rows() == 0) reject(source, "mesh has no faces");

  for (Eigen::Index v = 0; v < V.rows(); ++v) {
    if (!V.row(v).allFinite()) {
      std::ostringstream out;
      out << "vertex " << v << " has a non-finite coordinate (" << V(v, 0) << ", " << V(v, 1)
          << ", " << V(v, 2) << ")";
      reject(source, out.str());
    }
    // Patient coordinates in mm: anything beyond 100 m is a unit or export error, and
    // would overflow the geometry (squared lengths, cross products) downstream.
    if (V.row(v).cwiseAbs().maxCoeff() > kMaxCoordinateMm) {
      std::ostringstream out;
      out << "vertex " << v << " lies implausibly far from the origin (" << V(v, 0) << ", " << V(v, 1) << ", "
          << V(v, 2) << "); coordinates must be millimetres within 100 m";
      reject(source, out.str());
    }
  }

  const auto nv = V.rows();
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int i = F(f, k);
      if (i < 0 || i >= nv) {
        reject(source, "face " + std::to_string(f) + " has vertex index " + std::to_string(i) +
                           " but the mesh has " + std::to_string(nv) + " vertices");
      }
    }
    if (F(f, 0) == F(f, 1) || F(f, 1) == F(f, 2) || F(f, 0) == F(f, 2)) {
      reject(source, "face " + std::to_string(f) + " repeats a vertex index (" +
                         std::to_string(F(f, 0)) + ", " + std::to_string(F(f, 1)) + ", " +
                         std::to_string(F(f, 2)) + ")");
    }
  }

  // Corners that coincide without being one vertex: triangles that do not share their
  // corners (a PLY or OBJ written per triangle, a seam split for texture coordinates). The
  // deformation moves each copy on its own and tears the surface open there (22.8 mm on an
  // iliac written so, in an independent test), so such a mesh is refused rather than torn.
  {
    std::vector<char> used(static_cast<std::size_t>(nv), 0);
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      for (int k = 0; k < 3; ++k) used[static_cast<std::size_t>(F(f, k))] = 1;
    std::vector<int> order;
    for (Eigen::Index v = 0; v < nv; ++v)
      if (used[static_cast<std::size_t>(v)]) order.push_back(static_cast<int>(v));
    const auto key_less = [&](int a, int b) {
      for (int c = 0; c < 3; ++c)
        if (V(a, c) != V(b, c)) return V(a, c) < V(b, c);
      return false;
    };
    std::sort(order.begin(), order.end(), key_less);
    std::size_t coinciding = 0;
    int first_a = -1, first_b = -1;
    for (std::size_t i = 1; i < order.size(); ++i)
      if (!key_less(order[i - 1], order[i])) {
        ++coinciding;
        if (first_a < 0) first_a = order[i - 1], first_b = order[i];
      }
    if (coinciding > 0) {
      std::ostringstream out;
      out << coinciding << " vertices lie exactly on another vertex without being joined to it (first: " << first_a
          << " and " << first_b << " at (" << V(first_a, 0) << ", " << V(first_a, 1) << ", " << V(first_a, 2)
          << ")): the triangles do not share their corners, and deforming them would tear the surface apart; "
             "weld the mesh first (e.g. MeshLab's Merge Close Vertices, or save it as STL, which is welded on reading)";
      reject(source, out.str());
    }
  }

  // Sorting one 64-bit key per face edge is O(F log F) and cache friendly; runs of
  // equal keys are the faces sharing that edge.
  std::vector<std::uint64_t> keys;
  keys.reserve(static_cast<std::size_t>(F.rows()) * 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) keys.push_back(edge_key(F(f, k), F(f, (k + 1) % 3)));
  }
  std::sort(keys.begin(), keys.end());
  for (std::size_t i = 0; i < keys.size();) {
    std::size_t j = i + 1;
    while (j < keys.size() && keys[j] == keys[i]) ++j;
    if (j - i > 2) {
      const int a = static_cast<int>(keys[i] >> 32);
      const int b = static_cast<int>(keys[i] & 0xffffffffu);
      reject(source, "non-manifold edge (" + std::to_string(a) + ", " + std::to_string(b) +
                         ") is shared by " + std::to_string(j - i) + " faces (" +
                         faces_using_edge(F, a, b) + ")");
    }
    i = j;
  }
}

double mean_edge_length(const TriangleMesh& mesh) {
  const auto& V = mesh.V;
  const auto& F = mesh.F;
  if (F.rows() == 0) return 0.0;
  double sum = 0.0;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int a = F(f, k);
      const int b = F(f, (k + 1) % 3);
      if (a < 0 || a >= V.rows() || b < 0 || b >= V.rows()) {
        throw std::out_of_range("mean_edge_length: face " + std::to_string(f) +
                                " has a vertex index out of range");
      }
      sum += (V.row(a) - V.row(b)).norm();
    }
  }
  return sum / (3.0 * static_cast<double>(F.rows()));
}

double enclosed_volume(const TriangleMesh& mesh) {
  double six_v = 0.0;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)).transpose();
    const Eigen::Vector3d b = mesh.V.row(mesh.F(f, 1)).transpose();
    const Eigen::Vector3d c = mesh.V.row(mesh.F(f, 2)).transpose();
    six_v += a.dot(b.cross(c));
  }
  return six_v / 6.0;
}

bool is_closed(const TriangleMesh& mesh) {
  std::vector<std::uint64_t> edges;
  edges.reserve(static_cast<std::size_t>(mesh.F.rows()) * 3);
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const auto a = static_cast<std::uint32_t>(mesh.F(f, k)), b = static_cast<std::uint32_t>(mesh.F(f, (k + 1) % 3));
      edges.push_back((std::uint64_t{std::min(a, b)} << 32) | std::max(a, b));
    }
  std::sort(edges.begin(), edges.end());
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if (j - i != 2) return false;
    i = j;
  }
  return !edges.empty();
}

double median_edge_length(const TriangleMesh& mesh) {
  std::vector<double> lengths;
  lengths.reserve(static_cast<std::size_t>(mesh.F.rows()) * 3);
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) lengths.push_back((mesh.V.row(mesh.F(f, k)) - mesh.V.row(mesh.F(f, (k + 1) % 3))).norm());
  if (lengths.empty()) return 0.0;
  const auto mid = lengths.begin() + static_cast<std::ptrdiff_t>(lengths.size() / 2);
  std::nth_element(lengths.begin(), mid, lengths.end());
  return *mid;
}

}  // namespace evar::geometry
