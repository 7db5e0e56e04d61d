#include "isotropic_remesh.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <utility>
#include <vector>

#include <Eigen/Geometry>


namespace evar::deform::detail {

namespace {

using Vec = Eigen::Vector3d;
using Face = std::array<int, 3>;

// The faces on one edge: two inside a surface, one on its rim; more only where the input is
// not a manifold (then the count is right and the first four are kept).
struct EdgeFaces {
  std::array<int, 4> face{};
  std::size_t count = 0;
  void push_back(int f) {
    if (count < face.size()) face[count] = f;
    ++count;
  }
  std::size_t size() const { return count; }
  int operator[](std::size_t k) const { return face[k]; }
  const int* begin() const { return face.data(); }
  const int* end() const { return face.data() + std::min(count, face.size()); }
};

// The mesh being remeshed: faces and vertices are killed, never reused, and compacted at
// the end; vf holds each vertex's live faces.
class Remesher {
 public:
  Remesher(const geometry::TriangleMesh& m, double edge_mm)
      : lo_(0.8 * edge_mm), hi_(4.0 / 3.0 * edge_mm) {
    const auto n = static_cast<std::size_t>(m.V.rows());
    P_.resize(n);
    for (std::size_t i = 0; i < n; ++i) P_[i] = m.V.row(static_cast<Eigen::Index>(i)).transpose();
    F_.resize(static_cast<std::size_t>(m.F.rows()));
    vf_.resize(n);
    for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
      for (int k = 0; k < 3; ++k) {
        F_[static_cast<std::size_t>(f)][static_cast<std::size_t>(k)] = m.F(f, k);
        vf_[static_cast<std::size_t>(m.F(f, k))].push_back(static_cast<int>(f));
      }
    }
    face_alive_.assign(F_.size(), 1);
    vertex_alive_.assign(n, 1);
    // Vertices on an edge with one face are the open mesh's rim: they only collapse along it.
    // Each face names its vertex's neighbours along its two edges there; a neighbour named
    // once is across a rim edge. Wound consistently, a neighbour named twice follows the
    // vertex in exactly one of the two faces.
    rim_.assign(n, 0);
    std::vector<int>& named = scratch_u_;
    std::vector<int>& after = scratch_v_;
    for (std::size_t a = 0; a < n; ++a) {
      named.clear();
      after.clear();
      for (const int f : vf_[a]) {
        const Face& t = F_[idx(f)];
        const std::size_t k = corner(t, static_cast<int>(a));
        after.push_back(t[(k + 1) % 3]);
        named.push_back(t[(k + 1) % 3]);
        named.push_back(t[(k + 2) % 3]);
      }
      std::sort(named.begin(), named.end());
      std::sort(after.begin(), after.end());
      for (std::size_t k = 0; k < named.size();) {
        std::size_t end = k + 1;
        while (end < named.size() && named[end] == named[k]) ++end;
        if (end - k == 1) rim_[a] = rim_[idx(named[k])] = 1;
        const auto follows = std::equal_range(after.begin(), after.end(), named[k]);
        if (end - k == 2 && follows.second - follows.first != 1) wound_consistently_ = false;
        k = end;
      }
    }
  }

  void split_long_edges() {
    for (const auto& [u, v] : edges()) {
      if (!((P_[idx(u)] - P_[idx(v)]).norm() > hi_)) continue;
      const EdgeFaces faces = edge_faces(u, v);
      // Two faces with the same third vertex (a two-sided triangle) would give the new
      // vertex the same edge to it twice.
      if (faces.size() != 2 || opposite(faces[0], u, v) == opposite(faces[1], u, v)) continue;
      split(u, v);
    }
  }

  void collapse_short_edges() {
    auto list = edges();
    std::vector<double> length(list.size());
    for (std::size_t i = 0; i < list.size(); ++i) length[i] = (P_[idx(list[i].first)] - P_[idx(list[i].second)]).norm();
    std::vector<std::size_t> order(list.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return length[a] < length[b]; });
    for (const std::size_t i : order) {
      const auto [u, v] = list[i];
      if (!vertex_alive_[idx(u)] || !vertex_alive_[idx(v)]) continue;
      if ((P_[idx(u)] - P_[idx(v)]).norm() >= lo_) continue;
      try_collapse(u, v);
    }
  }

  void equalize_valences() {
    for (const auto& [u, v] : edges()) try_flip(u, v);
  }

  // Each free vertex moves to its neighbours' centroid within its tangent plane (Jacobi).
  // Off the rim each neighbour shares two of the vertex's faces, so the faces' other corners
  // count every neighbour twice: their mean is the neighbours'.
  void relax_tangentially() {
    std::vector<Vec> next = P_;
    for (std::size_t v = 0; v < P_.size(); ++v) {
      if (!vertex_alive_[v] || rim_[v] || vf_[v].empty()) continue;
      Vec c = Vec::Zero();
      for (const int f : vf_[v])
        for (const int w : F_[idx(f)])
          if (idx(w) != v) c += P_[idx(w)];
      c /= static_cast<double>(2 * vf_[v].size());
      Vec n = Vec::Zero();
      for (const int f : vf_[v]) n += face_normal(f);
      if (!(n.norm() > 0.0)) continue;
      n.normalize();
      next[v] = c + n.dot(P_[v] - c) * n;
    }
    P_ = std::move(next);
  }

  void project_onto(const geometry::RayCaster& surface) {
    for (std::size_t v = 0; v < P_.size(); ++v)
      if (vertex_alive_[v] && !rim_[v])
        if (const auto q = surface.closest_point(P_[v])) P_[v] = q->point;
  }

  geometry::TriangleMesh compact() const {
    std::vector<int> remap(P_.size(), -1);
    int kept = 0;
    for (std::size_t f = 0; f < F_.size(); ++f)
      if (face_alive_[f])
        for (const int v : F_[f])
          if (remap[idx(v)] < 0) remap[idx(v)] = kept++;
    geometry::TriangleMesh out;
    out.V.resize(kept, 3);
    for (std::size_t v = 0; v < P_.size(); ++v)
      if (remap[v] >= 0) out.V.row(remap[v]) = P_[v].transpose();
    const auto faces = std::count(face_alive_.begin(), face_alive_.end(), 1);
    out.F.resize(faces, 3);
    Eigen::Index row = 0;
    for (std::size_t f = 0; f < F_.size(); ++f) {
      if (!face_alive_[f]) continue;
      for (int k = 0; k < 3; ++k) out.F(row, k) = remap[idx(F_[f][static_cast<std::size_t>(k)])];
      ++row;
    }
    return out;
  }

 private:
  static std::size_t idx(int i) { return static_cast<std::size_t>(i); }
  // Where vertex v is in face t.
  static std::size_t corner(const Face& t, int v) { return t[0] == v ? 0 : t[1] == v ? 1 : 2; }

  // Every edge once, as (smaller, larger) vertex, in lexicographic order: per vertex, its
  // larger neighbours, sorted. On a consistently wound surface an edge inside it runs a→b
  // in one of its faces, so a finds b as the vertex after it in one of its faces; a rim edge
  // has one face, and a may find b before it there instead. (Splits, collapses and flips
  // keep the winding.)
  std::vector<std::pair<int, int>> edges() const {
    std::vector<std::pair<int, int>> e;
    e.reserve(3 * P_.size());
    std::vector<int>& larger = scratch_edges_;
    for (std::size_t a = 0; a < P_.size(); ++a) {
      larger.clear();
      for (const int f : vf_[a]) {
        const Face& t = F_[idx(f)];
        const std::size_t k = corner(t, static_cast<int>(a));
        const int after = t[(k + 1) % 3], before = t[(k + 2) % 3];
        if (idx(after) > a) larger.push_back(after);
        if (idx(before) > a && (!wound_consistently_ || (rim_[a] && rim_[idx(before)]))) larger.push_back(before);
      }
      std::sort(larger.begin(), larger.end());
      larger.erase(std::unique(larger.begin(), larger.end()), larger.end());
      for (const int b : larger) e.emplace_back(static_cast<int>(a), b);
    }
    return e;
  }

  int opposite(int f, int u, int v) const {
    for (const int w : F_[idx(f)])
      if (w != u && w != v) return w;
    return -1;
  }
  bool has(int f, int v) const {
    const Face& t = F_[idx(f)];
    return t[0] == v || t[1] == v || t[2] == v;
  }
  EdgeFaces edge_faces(int u, int v) const {
    EdgeFaces out;
    for (const int f : vf_[idx(u)])
      if (has(f, v)) out.push_back(f);
    return out;
  }
  void neighbours(int v, std::vector<int>& out) const {
    out.clear();
    for (const int f : vf_[idx(v)])
      for (const int w : F_[idx(f)])
        if (w != v) out.push_back(w);
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
  }
  int valence(int v) const {
    // Faces around an inner vertex; one more neighbour than faces on a rim.
    return static_cast<int>(vf_[idx(v)].size()) + (rim_[idx(v)] ? 1 : 0);
  }
  int target_valence(int v) const { return rim_[idx(v)] ? 4 : 6; }
  Vec face_normal(int f, int moved = -1, const Vec& to = Vec::Zero(), int replaced = -1, int by = -1) const {
    std::array<Vec, 3> p;
    for (std::size_t k = 0; k < 3; ++k) {
      int w = F_[idx(f)][k];
      if (w == replaced) w = by;
      p[k] = w == moved ? to : P_[idx(w)];
    }
    return (p[1] - p[0]).cross(p[2] - p[0]);
  }
  // The face rotated so that it reads (a, b, c) with a→b one of its edges; false if the
  // edge u→v does not run that way in it.
  bool rotated(int f, int a, int b, Face& out) const {
    const Face& t = F_[idx(f)];
    for (std::size_t k = 0; k < 3; ++k)
      if (t[k] == a && t[(k + 1) % 3] == b) {
        out = {t[k], t[(k + 1) % 3], t[(k + 2) % 3]};
        return true;
      }
    return false;
  }
  void drop(int v, int f) {
    auto& l = vf_[idx(v)];
    l.erase(std::find(l.begin(), l.end(), f));
  }

  void split(int u, int v) {
    const int m = static_cast<int>(P_.size());
    P_.push_back(0.5 * (P_[idx(u)] + P_[idx(v)]));
    vf_.emplace_back();
    vertex_alive_.push_back(1);
    rim_.push_back(0);
    for (const int f : edge_faces(u, v)) {
      Face t{};
      if (!rotated(f, u, v, t)) rotated(f, v, u, t);
      const int x = t[0], y = t[1], z = t[2];
      const int g = static_cast<int>(F_.size());
      F_[idx(f)] = {x, m, z};
      F_.push_back({m, y, z});
      face_alive_.push_back(1);
      drop(y, f);
      vf_[idx(y)].push_back(g);
      vf_[idx(z)].push_back(g);
      vf_[idx(m)].push_back(f);
      vf_[idx(m)].push_back(g);
    }
  }

  // The edges of v that bound the mesh (one face).
  int rim_edges(int v, const std::vector<int>& nb) const {
    int count = 0;
    for (const int w : nb)
      if (edge_faces(v, w).size() == 1) ++count;
    return count;
  }

  // u goes, v stays. Inside, v moves to the edge's midpoint; a vertex collapses onto a rim
  // vertex where that one is; along a rim, u goes into v, which keeps its place, so the
  // rim's vertices stay rim vertices of the input.
  bool try_collapse(int u, int v) {
    if (rim_[idx(u)] && !rim_[idx(v)]) std::swap(u, v);
    const EdgeFaces shared = edge_faces(u, v);
    const bool along_rim = rim_[idx(u)];
    if (along_rim ? shared.size() != 1 : shared.size() != 2) return false;
    std::vector<int>& nu = scratch_u_;
    std::vector<int>& nv = scratch_v_;
    std::vector<int>& common = scratch_common_;
    neighbours(u, nu);
    neighbours(v, nv);
    common.clear();
    // A rim vertex where more than one rim passes (two open ends touching) stays.
    if (along_rim && (rim_edges(u, nu) != 2 || rim_edges(v, nv) != 2)) return false;
    std::set_intersection(nu.begin(), nu.end(), nv.begin(), nv.end(), std::back_inserter(common));
    // Link condition: only the opposite vertices of the edge's faces are shared, and they
    // keep three neighbours at least.
    if (common.size() != shared.size()) return false;
    for (const int w : common)
      if (valence(w) <= 3) return false;
    if (valence(u) + valence(v) - 4 < 3) return false;
    if (along_rim && nu.size() + nv.size() <= 4) return false;  // a rim of three vertices stays
    const Vec p = rim_[idx(v)] ? P_[idx(v)] : Vec(0.5 * (P_[idx(u)] + P_[idx(v)]));
    for (const auto* list : {&nu, &nv})
      for (const int w : *list)
        if (w != u && w != v && (p - P_[idx(w)]).norm() > hi_) return false;
    // No face may turn over or by more than 60°.
    for (const int x : {u, v})
      for (const int f : vf_[idx(x)]) {
        if (std::find(shared.begin(), shared.end(), f) != shared.end()) continue;
        const Vec before = face_normal(f), after = face_normal(f, v, p, u, v);
        if (!(after.dot(before) > 0.5 * after.norm() * before.norm())) return false;
      }
    for (const int f : shared) {
      face_alive_[idx(f)] = 0;
      for (const int w : F_[idx(f)]) drop(w, f);
    }
    for (const int f : vf_[idx(u)]) {
      for (int& w : F_[idx(f)])
        if (w == u) w = v;
      vf_[idx(v)].push_back(f);
    }
    vf_[idx(u)].clear();
    vertex_alive_[idx(u)] = 0;
    P_[idx(v)] = p;
    return true;
  }

  bool try_flip(int u, int v) {
    const EdgeFaces shared = edge_faces(u, v);
    if (shared.size() != 2) return false;
    Face t1{}, t2{};
    int f1 = shared[0], f2 = shared[1];
    if (!rotated(f1, u, v, t1)) std::swap(f1, f2);
    if (!rotated(f1, u, v, t1) || !rotated(f2, v, u, t2)) return false;  // inconsistent orientation
    const int a = t1[2], b = t2[2];
    if (a == b) return false;
    for (const int f : vf_[idx(a)])
      if (has(f, b)) return false;  // a–b is an edge already
    if (valence(u) <= 3 || valence(v) <= 3) return false;
    const auto dev = [&](int w, int change) {
      const int d = valence(w) + change - target_valence(w);
      return d * d;
    };
    const int before = dev(u, 0) + dev(v, 0) + dev(a, 0) + dev(b, 0);
    const int after = dev(u, -1) + dev(v, -1) + dev(a, 1) + dev(b, 1);
    if (after >= before) return false;
    // The quad must stay a surface: the new faces agree with each other and the old ones.
    const Vec n_old = face_normal(f1).normalized() + face_normal(f2).normalized();
    const Vec& pa = P_[idx(a)];
    const Vec n1 = (P_[idx(u)] - pa).cross(P_[idx(b)] - pa), n2 = (P_[idx(v)] - P_[idx(b)]).cross(pa - P_[idx(b)]);
    if (!(n1.dot(n2) > 0.0 && n1.dot(n_old) > 0.0 && n2.dot(n_old) > 0.0)) return false;
    F_[idx(f1)] = {a, u, b};
    F_[idx(f2)] = {b, v, a};
    drop(u, f2);
    drop(v, f1);
    vf_[idx(a)].push_back(f2);
    vf_[idx(b)].push_back(f1);
    return true;
  }

  double lo_, hi_;
  bool wound_consistently_ = true;
  // try_collapse's neighbour lists, kept between calls so that they are not reallocated.
  std::vector<int> scratch_u_, scratch_v_, scratch_common_;
  mutable std::vector<int> scratch_edges_;
  std::vector<Vec> P_;
  std::vector<Face> F_;
  std::vector<char> face_alive_, vertex_alive_, rim_;
  std::vector<std::vector<int>> vf_;
};

}  // namespace

geometry::TriangleMesh isotropic_remesh(const geometry::TriangleMesh& surface, const geometry::RayCaster& surface_bvh,
                                        double edge_mm, int iterations) {
  if (!(edge_mm > 0.0) || !std::isfinite(edge_mm))
    throw std::invalid_argument("isotropic remesh: the edge length must be positive and finite");
  Remesher r(surface, edge_mm);
  for (int i = 0; i < iterations; ++i) {
    r.split_long_edges();
    r.collapse_short_edges();
    r.equalize_valences();
    r.relax_tangentially();
    r.project_onto(surface_bvh);
  }
  return r.compact();
}

}  // namespace evar::deform::detail
