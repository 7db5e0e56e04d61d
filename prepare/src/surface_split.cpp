#include "evar/prepare/surface_split.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <queue>
#include <unordered_map>
#include <vector>

#include "evar/base/input_error.hpp"
#include "evar/base/quantity_text.hpp"
#include "evar/geometry/ray_caster.hpp"

namespace evar::prepare {
namespace {

// Margin (mm) by which two lumens must have parted before a cut: the surface between
// them (the crotch) lies above it.
constexpr double kPartedByMm = 1.0;

// The faces `keep` marks, as a mesh of its own (vertices renumbered in their old order).
geometry::TriangleMesh piece(const geometry::TriangleMesh& mesh, const std::vector<char>& keep) {
  std::vector<int> index(static_cast<std::size_t>(mesh.V.rows()), -1);
  int faces = 0;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    if (keep[static_cast<std::size_t>(f)]) {
      ++faces;
      for (int k = 0; k < 3; ++k) index[static_cast<std::size_t>(mesh.F(f, k))] = 0;
    }
  int vertices = 0;
  for (auto& i : index)
    if (i == 0) i = vertices++;
  geometry::TriangleMesh out;
  out.V.resize(vertices, 3);
  for (Eigen::Index v = 0; v < mesh.V.rows(); ++v)
    if (index[static_cast<std::size_t>(v)] >= 0) out.V.row(index[static_cast<std::size_t>(v)]) = mesh.V.row(v);
  out.F.resize(faces, 3);
  int f_out = 0;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    if (keep[static_cast<std::size_t>(f)]) {
      for (int k = 0; k < 3; ++k) out.F(f_out, k) = index[static_cast<std::size_t>(mesh.F(f, k))];
      ++f_out;
    }
  return out;
}

// Faces sharing an edge with each face.
std::vector<std::vector<int>> face_neighbours(const geometry::TriangleMesh& mesh) {
  std::unordered_map<std::uint64_t, std::vector<int>> by_edge;
  by_edge.reserve(static_cast<std::size_t>(3 * mesh.F.rows()));
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      auto a = static_cast<std::uint32_t>(mesh.F(f, k)), b = static_cast<std::uint32_t>(mesh.F(f, (k + 1) % 3));
      if (a > b) std::swap(a, b);
      by_edge[(static_cast<std::uint64_t>(a) << 32) | b].push_back(static_cast<int>(f));
    }
  std::vector<std::vector<int>> out(static_cast<std::size_t>(mesh.F.rows()));
  for (const auto& [edge, faces] : by_edge)
    for (const int f : faces)
      for (const int g : faces)
        if (f != g) out[static_cast<std::size_t>(f)].push_back(g);
  return out;
}

}  // namespace

std::vector<double> radius_from_surface(const geometry::RayCaster& surface, const geometry::Polyline& centerline) {
  std::vector<double> r;
  r.reserve(centerline.size());
  for (const auto& p : centerline) {
    const auto q = surface.closest_point(p);
    r.push_back(q ? q->distance_mm : 0.0);
  }
  return r;
}

SurfacePieces split_surface(const geometry::TriangleMesh& surface, const geometry::RayCaster& caster,
                            const BifurcationTree& tree, const std::string& source) {
  SurfacePieces out;
  const Eigen::Index nf = surface.F.rows();
  std::vector<Eigen::Vector3d> centroid(static_cast<std::size_t>(nf));
  for (Eigen::Index f = 0; f < nf; ++f)
    centroid[static_cast<std::size_t>(f)] =
        (surface.V.row(surface.F(f, 0)) + surface.V.row(surface.F(f, 1)) + surface.V.row(surface.F(f, 2))).transpose() / 3.0;
  const auto neighbours = face_neighbours(surface);
  std::vector<char> taken(static_cast<std::size_t>(nf), 0);

  for (int b = 0; b < 2; ++b) {
    const auto& branch = tree.branches[static_cast<std::size_t>(b)];
    const auto& other = tree.branches[static_cast<std::size_t>(1 - b)];
    const auto& r = tree.branch_radius_mm[static_cast<std::size_t>(b)];
    const auto& r_other = tree.branch_radius_mm[static_cast<std::size_t>(1 - b)];
    if (r.size() != branch.size() || r_other.size() != other.size())
      throw std::invalid_argument("split_surface: the tree's branches need a radius per point");
    const auto arc = geometry::arc_lengths(branch);
    const geometry::PolylineProjector onto_other(other);
    const auto other_arc = geometry::arc_lengths(other);
    // Where this lumen has parted from the other's: its wall and the other's clear of
    // each other by the margin.
    std::size_t parted = branch.size();
    for (std::size_t k = 0; k < branch.size(); ++k) {
      const auto at = onto_other.project(branch[k]);
      const auto j = static_cast<std::size_t>(std::upper_bound(other_arc.begin(), other_arc.end(), at.arc_length_mm) -
                                              other_arc.begin() - 1);
      if (at.distance_mm > r[k] + r_other[std::min(j, other.size() - 1)] + kPartedByMm) {
        parted = k;
        break;
      }
    }
    if (parted == branch.size())
      throw base::InputError(source + ": the lumen of iliac path " + std::to_string(b + 1) +
                             " never parts from the other's (their walls stay within " + base::quantity_text(kPartedByMm, "mm", 1) +
                             " of each other down to the outlet): is it one vessel?");
    const double s_cut = std::min(arc[parted] + 0.5 * r[parted], 0.5 * (arc[parted] + arc.back()));
    const Eigen::Vector3d c = geometry::point_at(branch, arc, s_cut);
    const Eigen::Vector3d t = geometry::tangent_at(branch, arc, s_cut);
    out.cut_arc_mm[static_cast<std::size_t>(b)] = s_cut;
    out.cut_centre[static_cast<std::size_t>(b)] = c;
    out.cut_normal[static_cast<std::size_t>(b)] = t;

    // The faces beyond the plane, nearer this branch than the other, connected to the
    // outlet's.
    const auto seed = caster.closest_point(branch.back());
    if (!seed) throw base::InputError(source + ": the surface has no faces");
    const geometry::PolylineProjector onto_this(branch);
    const auto belongs = [&](int f) {
      const Eigen::Vector3d& x = centroid[static_cast<std::size_t>(f)];
      if ((x - c).dot(t) <= 0.0) return false;
      return onto_this.project(x).distance_mm <= onto_other.project(x).distance_mm;
    };
    std::vector<char> in(static_cast<std::size_t>(nf), 0);
    std::queue<int> todo;
    if (belongs(seed->face) && !taken[static_cast<std::size_t>(seed->face)]) {
      in[static_cast<std::size_t>(seed->face)] = 1;
      todo.push(seed->face);
    }
    std::size_t count = 0;
    while (!todo.empty()) {
      const int f = todo.front();
      todo.pop();
      ++count;
      for (const int g : neighbours[static_cast<std::size_t>(f)])
        if (!in[static_cast<std::size_t>(g)] && !taken[static_cast<std::size_t>(g)] && belongs(g)) {
          in[static_cast<std::size_t>(g)] = 1;
          todo.push(g);
        }
    }
    if (count == 0 || count > static_cast<std::size_t>(0.6 * static_cast<double>(nf)))
      throw base::InputError(source + ": cutting iliac path " + std::to_string(b + 1) + " " + base::quantity_text(s_cut, "mm", 1) +
                             " below where the paths part leaves " +
                             (count == 0 ? std::string("nothing beyond the cut") : std::string("most of the surface beyond it")) +
                             ": do the centerlines belong to this surface (same coordinates)?");
    for (Eigen::Index f = 0; f < nf; ++f)
      if (in[static_cast<std::size_t>(f)]) taken[static_cast<std::size_t>(f)] = 1;
    out.iliacs[static_cast<std::size_t>(b)] = piece(surface, in);
  }
  std::vector<char> rest(static_cast<std::size_t>(nf));
  for (Eigen::Index f = 0; f < nf; ++f) rest[static_cast<std::size_t>(f)] = !taken[static_cast<std::size_t>(f)];
  out.aorta = piece(surface, rest);
  return out;
}

}  // namespace evar::prepare
