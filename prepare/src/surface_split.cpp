#include "evar/prepare/surface_split.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <queue>
#include <unordered_map>
#include <vector>

#include <Eigen/Geometry>

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

// Vertices closer to a cut plane than this share of the median edge are moved onto it (where
// no face round them turns over or collapses), so the cut makes no sliver beside them.
constexpr double kSnapShareOfEdge = 0.2;

// `mesh` with its faces that cross the plane through `c` square to the unit `t` split along
// it, where the crossing starts at a face `starts` accepts and as far as the crossing runs
// on from there (so every edge split is split in both its faces). New vertices lie on the
// plane, shared by the faces round them; faces keep their winding.
template <class Starts>
void cut_along_plane(geometry::TriangleMesh& mesh, const Eigen::Vector3d& c, const Eigen::Vector3d& t, Starts starts) {
  const Eigen::Index nv = mesh.V.rows(), nf = mesh.F.rows();
  const double snap = kSnapShareOfEdge * geometry::median_edge_length(mesh);
  std::vector<double> d(static_cast<std::size_t>(nv));
  for (Eigen::Index v = 0; v < nv; ++v) d[static_cast<std::size_t>(v)] = (mesh.V.row(v).transpose() - c).dot(t);
  const auto crosses = [&](Eigen::Index f) {
    double lo = INFINITY, hi = -INFINITY;
    for (int k = 0; k < 3; ++k) {
      const double x = d[static_cast<std::size_t>(mesh.F(f, k))];
      lo = std::min(lo, x), hi = std::max(hi, x);
    }
    return lo < 0.0 && hi > 0.0;
  };
  // The crossing faces, from those `starts` accepts along the crossing.
  const auto neighbours = face_neighbours(mesh);
  std::vector<char> split(static_cast<std::size_t>(nf), 0);
  std::queue<Eigen::Index> todo;
  for (Eigen::Index f = 0; f < nf; ++f)
    if (crosses(f) && starts(f)) split[static_cast<std::size_t>(f)] = 1, todo.push(f);
  while (!todo.empty()) {
    const Eigen::Index f = todo.front();
    todo.pop();
    for (const int g : neighbours[static_cast<std::size_t>(f)])
      if (!split[static_cast<std::size_t>(g)] && crosses(g)) split[static_cast<std::size_t>(g)] = 1, todo.push(g);
  }
  // Onto the plane: their vertices that nearly lie on it (a face then may no longer cross),
  // unless that would turn a face round the vertex over or leave it almost without area
  // (a sliver beside the plane).
  std::vector<std::vector<Eigen::Index>> faces_of(static_cast<std::size_t>(nv));
  for (Eigen::Index f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) faces_of[static_cast<std::size_t>(mesh.F(f, k))].push_back(f);
  const auto area_normal = [&](Eigen::Index f, Eigen::Index moved, const Eigen::Vector3d& to) {
    std::array<Eigen::Vector3d, 3> p;
    for (int k = 0; k < 3; ++k) p[static_cast<std::size_t>(k)] = mesh.F(f, k) == moved ? to : mesh.V.row(mesh.F(f, k)).transpose();
    return Eigen::Vector3d((p[1] - p[0]).cross(p[2] - p[0]));
  };
  for (Eigen::Index f = 0; f < nf; ++f)
    if (split[static_cast<std::size_t>(f)])
      for (int k = 0; k < 3; ++k) {
        const Eigen::Index v = mesh.F(f, k);
        double& x = d[static_cast<std::size_t>(v)];
        if (x == 0.0 || !(std::abs(x) < snap)) continue;
        const Eigen::Vector3d to = mesh.V.row(v).transpose() - x * t;
        bool harmless = true;
        for (const Eigen::Index g : faces_of[static_cast<std::size_t>(v)]) {
          const Eigen::Vector3d before = area_normal(g, -1, to), after = area_normal(g, v, to);
          if (!(after.dot(before) > 0.0 && after.norm() > 0.1 * before.norm())) harmless = false;
        }
        if (!harmless) continue;
        mesh.V.row(v) = to.transpose();
        x = 0.0;
      }
  std::vector<Eigen::Vector3d> added;
  std::unordered_map<std::uint64_t, int> on_edge;
  const auto crossing = [&](int a, int b) {
    const auto key = (static_cast<std::uint64_t>(std::min(a, b)) << 32) | static_cast<std::uint32_t>(std::max(a, b));
    const auto [it, fresh] = on_edge.try_emplace(key, static_cast<int>(nv + static_cast<Eigen::Index>(added.size())));
    if (fresh) {
      const double da = d[static_cast<std::size_t>(a)], db = d[static_cast<std::size_t>(b)];
      added.push_back(mesh.V.row(a).transpose() + da / (da - db) * (mesh.V.row(b) - mesh.V.row(a)).transpose());
    }
    return it->second;
  };
  std::vector<std::array<int, 3>> faces;
  const auto emit = [&](int a, int b, int e) { faces.push_back({a, b, e}); };
  for (Eigen::Index f = 0; f < nf; ++f) {
    std::array<int, 3> v{mesh.F(f, 0), mesh.F(f, 1), mesh.F(f, 2)};
    if (!split[static_cast<std::size_t>(f)] || !crosses(f)) {
      emit(v[0], v[1], v[2]);
      continue;
    }
    const auto sign = [&](int k) {
      const double x = d[static_cast<std::size_t>(v[static_cast<std::size_t>(k)])];
      return (x > 0.0) - (x < 0.0);
    };
    // Turned so that v[0] is the one apart: on the plane, or alone on its side.
    int apart = 0;
    for (int k = 0; k < 3; ++k)
      if (sign(k) == 0 || (sign((k + 1) % 3) == sign((k + 2) % 3) && sign((k + 1) % 3) != sign(k))) apart = k;
    std::rotate(v.begin(), v.begin() + apart, v.end());
    if (d[static_cast<std::size_t>(v[0])] == 0.0) {
      const int p = crossing(v[1], v[2]);
      emit(v[0], v[1], p);
      emit(v[0], p, v[2]);
    } else {
      const int p = crossing(v[0], v[1]), q = crossing(v[0], v[2]);
      emit(v[0], p, q);
      emit(p, v[1], v[2]);
      emit(p, v[2], q);
    }
  }
  mesh.V.conservativeResize(nv + static_cast<Eigen::Index>(added.size()), 3);
  for (std::size_t k = 0; k < added.size(); ++k) mesh.V.row(nv + static_cast<Eigen::Index>(k)) = added[k].transpose();
  mesh.F.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (std::size_t k = 0; k < faces.size(); ++k)
    mesh.F.row(static_cast<Eigen::Index>(k)) << faces[k][0], faces[k][1], faces[k][2];
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
  // Where each branch is cut: a plane square to it, half a radius below where its lumen has
  // parted from the other's (their walls clear of each other by the margin).
  std::array<double, 2> r_cut{};
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
    out.cut_arc_mm[static_cast<std::size_t>(b)] = s_cut;
    out.cut_centre[static_cast<std::size_t>(b)] = geometry::point_at(branch, arc, s_cut);
    out.cut_normal[static_cast<std::size_t>(b)] = geometry::tangent_at(branch, arc, s_cut);
    r_cut[static_cast<std::size_t>(b)] = r[parted];
  }

  // The surface split along both planes round each branch, so each piece's rim is the plane's
  // section, not the faces' jagged edges.
  geometry::TriangleMesh mesh = surface;
  for (int b = 0; b < 2; ++b) {
    const Eigen::Vector3d c = out.cut_centre[static_cast<std::size_t>(b)];
    const geometry::PolylineProjector onto_this(tree.branches[static_cast<std::size_t>(b)]);
    const geometry::PolylineProjector onto_other(tree.branches[static_cast<std::size_t>(1 - b)]);
    const double reach = 2.0 * r_cut[static_cast<std::size_t>(b)] + 2.0;
    cut_along_plane(mesh, c, out.cut_normal[static_cast<std::size_t>(b)], [&](Eigen::Index f) {
      const Eigen::Vector3d x = (mesh.V.row(mesh.F(f, 0)) + mesh.V.row(mesh.F(f, 1)) + mesh.V.row(mesh.F(f, 2))).transpose() / 3.0;
      return (x - c).norm() <= reach && onto_this.project(x).distance_mm <= onto_other.project(x).distance_mm;
    });
  }

  const Eigen::Index nf = mesh.F.rows();
  std::vector<Eigen::Vector3d> centroid(static_cast<std::size_t>(nf));
  for (Eigen::Index f = 0; f < nf; ++f)
    centroid[static_cast<std::size_t>(f)] =
        (mesh.V.row(mesh.F(f, 0)) + mesh.V.row(mesh.F(f, 1)) + mesh.V.row(mesh.F(f, 2))).transpose() / 3.0;
  const auto neighbours = face_neighbours(mesh);
  std::vector<char> taken(static_cast<std::size_t>(nf), 0);
  for (int b = 0; b < 2; ++b) {
    const auto& branch = tree.branches[static_cast<std::size_t>(b)];
    const Eigen::Vector3d c = out.cut_centre[static_cast<std::size_t>(b)], t = out.cut_normal[static_cast<std::size_t>(b)];
    const geometry::PolylineProjector onto_this(branch);
    const geometry::PolylineProjector onto_other(tree.branches[static_cast<std::size_t>(1 - b)]);
    // The faces beyond the plane, nearer this branch than the other, connected to the
    // outlet's.
    const auto outlet = caster.closest_point(branch.back());
    if (!outlet) throw base::InputError(source + ": the surface has no faces");
    int seed = 0;
    for (Eigen::Index f = 1; f < nf; ++f)
      if ((centroid[static_cast<std::size_t>(f)] - outlet->point).squaredNorm() <
          (centroid[static_cast<std::size_t>(seed)] - outlet->point).squaredNorm())
        seed = static_cast<int>(f);
    const auto belongs = [&](int f) {
      const Eigen::Vector3d& x = centroid[static_cast<std::size_t>(f)];
      if ((x - c).dot(t) <= 0.0) return false;
      return onto_this.project(x).distance_mm <= onto_other.project(x).distance_mm;
    };
    std::vector<char> in(static_cast<std::size_t>(nf), 0);
    std::queue<int> todo;
    if (belongs(seed) && !taken[static_cast<std::size_t>(seed)]) {
      in[static_cast<std::size_t>(seed)] = 1;
      todo.push(seed);
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
    const double s_cut = out.cut_arc_mm[static_cast<std::size_t>(b)];
    if (count == 0 || count > static_cast<std::size_t>(0.6 * static_cast<double>(nf)))
      throw base::InputError(source + ": cutting iliac path " + std::to_string(b + 1) + " " + base::quantity_text(s_cut, "mm", 1) +
                             " below where the paths part leaves " +
                             (count == 0 ? std::string("nothing beyond the cut") : std::string("most of the surface beyond it")) +
                             ": do the centerlines belong to this surface (same coordinates)?");
    for (Eigen::Index f = 0; f < nf; ++f)
      if (in[static_cast<std::size_t>(f)]) taken[static_cast<std::size_t>(f)] = 1;
    out.iliacs[static_cast<std::size_t>(b)] = piece(mesh, in);
  }
  std::vector<char> rest(static_cast<std::size_t>(nf));
  for (Eigen::Index f = 0; f < nf; ++f) rest[static_cast<std::size_t>(f)] = !taken[static_cast<std::size_t>(f)];
  out.aorta = piece(mesh, rest);
  return out;
}

}  // namespace evar::prepare
