#include "evar/geometry/surface_side.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

namespace evar::geometry {
namespace {

int corner_of(const Faces& F, int f, int v) { return F(f, 0) == v ? 0 : (F(f, 1) == v ? 1 : 2); }

}  // namespace

SurfaceSide::SurfaceSide(const TriangleMesh& mesh, RayCaster::BuildQuality quality)
    : SurfaceSide(mesh, std::vector<char>{}, quality) {}

SurfaceSide::SurfaceSide(const TriangleMesh& mesh, std::vector<char> cap_faces, RayCaster::BuildQuality quality)
    : cap_faces_(std::move(cap_faces)) {
  if (!cap_faces_.empty() && cap_faces_.size() != static_cast<std::size_t>(mesh.F.rows()))
    throw std::invalid_argument("SurfaceSide: " + std::to_string(cap_faces_.size()) + " cap flags for " +
                                std::to_string(mesh.F.rows()) + " faces (one per face expected)");
  if (mesh.F.rows() > 0) caster_.emplace(mesh, quality);
  const auto& V = mesh.V;
  const auto& F = mesh.F;
  const Eigen::Index nf = F.rows();
  face_normals_.setZero(nf, 3);
  for (Eigen::Index f = 0; f < nf; ++f) {
    const Eigen::Vector3d n =
        (V.row(F(f, 1)) - V.row(F(f, 0))).transpose().cross((V.row(F(f, 2)) - V.row(F(f, 0))).transpose());
    const double len = n.norm();
    if (len > 0.0) face_normals_.row(f) = (n / len).transpose();  // a sliver of no area holds no direction
  }
  first_face_.assign(static_cast<std::size_t>(V.rows()) + 1, 0);
  for (Eigen::Index f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) ++first_face_[static_cast<std::size_t>(F(f, k)) + 1];
  for (std::size_t v = 0; v + 1 < first_face_.size(); ++v) first_face_[v + 1] += first_face_[v];
  faces_of_.resize(static_cast<std::size_t>(3 * nf));
  std::vector<int> fill(first_face_.begin(), first_face_.end() - 1);
  for (Eigen::Index f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) faces_of_[static_cast<std::size_t>(fill[static_cast<std::size_t>(F(f, k))]++)] = static_cast<int>(f);

  // The openings: boundary edges (held by one face) joined into loops by their vertices.
  std::vector<std::vector<int>> rim_next(static_cast<std::size_t>(V.rows()));
  for (Eigen::Index f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = F(f, k), b = F(f, (k + 1) % 3);
      bool shared = false;
      for (int l = first_face_[static_cast<std::size_t>(a)]; l < first_face_[static_cast<std::size_t>(a) + 1] && !shared; ++l) {
        const int g = faces_of_[static_cast<std::size_t>(l)];
        shared = g != f && (F(g, 0) == b || F(g, 1) == b || F(g, 2) == b);
      }
      if (!shared) rim_next[static_cast<std::size_t>(a)].push_back(b), rim_next[static_cast<std::size_t>(b)].push_back(a);
    }
  std::vector<char> seen(rim_next.size(), 0);
  for (std::size_t start = 0; start < rim_next.size(); ++start) {
    if (rim_next[start].empty() || seen[start]) continue;
    std::vector<int> loop{static_cast<int>(start)};
    seen[start] = 1;
    for (std::size_t k = 0; k < loop.size(); ++k)
      for (const int w : rim_next[static_cast<std::size_t>(loop[k])])
        if (!seen[static_cast<std::size_t>(w)]) seen[static_cast<std::size_t>(w)] = 1, loop.push_back(w);
    Opening o;
    for (const int v : loop) o.centre += V.row(v).transpose();
    o.centre /= static_cast<double>(loop.size());
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (const int v : loop) {
      const Eigen::Vector3d d = V.row(v).transpose() - o.centre;
      scatter += d * d.transpose();
    }
    o.normal = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvectors().col(0);
    for (const int v : loop) {
      const Eigen::Vector3d d = V.row(v).transpose() - o.centre;
      o.radius_mm = std::max(o.radius_mm, d.norm());
      o.half_thickness_mm = std::max(o.half_thickness_mm, std::abs(d.dot(o.normal)));
    }
    openings_.push_back(o);
  }
}

double SurfaceSide::inside_ball_radius_mm(const Eigen::Vector3d& p, double distance_mm) const {
  double r = 0.9 * distance_mm;
  for (const Opening& o : openings_) {
    const Eigen::Vector3d d = p - o.centre;
    if (d.norm() - o.radius_mm >= r) continue;  // the ball cannot reach its slab
    r = std::min(r, std::max(0.0, std::abs(d.dot(o.normal)) - o.half_thickness_mm));
  }
  return r;
}

Eigen::Vector3d SurfaceSide::rim_out(int face, int i, int j) const {
  const auto& V = mesh().V;
  const int k = mesh().F(face, 3 - corner_of(mesh().F, face, i) - corner_of(mesh().F, face, j));
  const Eigen::Vector3d a = V.row(i).transpose(), b = V.row(j).transpose();
  const Eigen::Vector3d t = (b - a).normalized();
  Eigen::Vector3d m = 0.5 * (a + b) - V.row(k).transpose();
  m -= m.dot(t) * t;
  return m.norm() > 0.0 ? Eigen::Vector3d(m.normalized()) : Eigen::Vector3d::Zero();
}

SurfaceSide::FeatureNormal SurfaceSide::at_edge(int face, int i, int j) const {
  FeatureNormal out;
  out.normal = face_normals_.row(face).transpose();
  out.on_cap = is_cap(face);
  bool shared = false;
  for (int k = first_face_[static_cast<std::size_t>(i)]; k < first_face_[static_cast<std::size_t>(i) + 1]; ++k) {
    const int g = faces_of_[static_cast<std::size_t>(k)];
    if (g != face && (mesh().F(g, 0) == j || mesh().F(g, 1) == j || mesh().F(g, 2) == j)) {
      out.normal += face_normals_.row(g).transpose();
      out.on_cap = out.on_cap || is_cap(g);
      shared = true;
    }
  }
  if (!shared) out.rim_out = rim_out(face, i, j);
  return out;
}

SurfaceSide::FeatureNormal SurfaceSide::at_vertex(int v) const {
  FeatureNormal out;
  const auto& V = mesh().V;
  const auto& F = mesh().F;
  const int begin = first_face_[static_cast<std::size_t>(v)], end = first_face_[static_cast<std::size_t>(v) + 1];
  for (int k = begin; k < end; ++k) {
    const int f = faces_of_[static_cast<std::size_t>(k)];
    const int c = corner_of(F, f, v);
    const int a = F(f, (c + 1) % 3), b = F(f, (c + 2) % 3);
    const Eigen::Vector3d u = (V.row(a) - V.row(v)).transpose().normalized();
    const Eigen::Vector3d w = (V.row(b) - V.row(v)).transpose().normalized();
    out.normal += std::acos(std::clamp(u.dot(w), -1.0, 1.0)) * face_normals_.row(f).transpose();
    out.on_cap = out.on_cap || is_cap(f);
    // Each of the vertex's two edges in this face on the rim when no other face around
    // the vertex holds it.
    for (const int other : {a, b}) {
      bool shared = false;
      for (int l = begin; l < end && !shared; ++l) {
        const int g = faces_of_[static_cast<std::size_t>(l)];
        shared = g != f && (F(g, 0) == other || F(g, 1) == other || F(g, 2) == other);
      }
      if (!shared) out.rim_out += rim_out(f, v, other);
    }
  }
  return out;
}

SidedPoint SurfaceSide::classify(const Eigen::Vector3d& p, double expected_distance_mm) const {
  SidedPoint out;
  std::optional<SurfacePoint> q;
  if (caster_ && expected_distance_mm >= 0.0 && std::isfinite(expected_distance_mm))
    q = caster_->closest_point(p, expected_distance_mm);
  if (caster_ && !q) q = caster_->closest_point(p);
  if (!q) {
    out.distance_mm = std::numeric_limits<double>::infinity();
    return out;
  }
  out.distance_mm = q->distance_mm;
  out.closest = q->point;
  if (!(q->distance_mm > 0.0)) {
    out.side = Side::Inside;  // on the wall counts as inside it
    return out;
  }
  // The feature holding q: corners with zero weight are not part of it (the closest point
  // of a triangle comes with exact zeros off its region).
  const Eigen::Vector3d& w = q->barycentric;
  const int f = q->face;
  const int zeros = (w[0] == 0.0) + (w[1] == 0.0) + (w[2] == 0.0);
  FeatureNormal at;
  if (zeros == 0) {
    at.normal = face_normals_.row(f).transpose();
    at.on_cap = is_cap(f);
  } else if (zeros == 1) {
    const int k = w[0] == 0.0 ? 0 : (w[1] == 0.0 ? 1 : 2);  // the edge opposite corner k
    at = at_edge(f, mesh().F(f, (k + 1) % 3), mesh().F(f, (k + 2) % 3));
  } else {
    at = at_vertex(mesh().F(f, w[0] != 0.0 ? 0 : (w[1] != 0.0 ? 1 : 2)));
  }
  if (!(at.normal.norm() > 0.0)) return out;  // only slivers of no area there: no direction to tell by
  const Eigen::Vector3d u = (p - q->point) / q->distance_mm;
  const double through_wall = u.dot(at.normal.normalized());
  const double past_rim = at.rim_out.norm() > 0.0 ? u.dot(at.rim_out.normalized()) : 0.0;
  if (past_rim <= 0.0)
    out.side = through_wall > 0.0 ? Side::Outside : Side::Inside;
  else
    out.side = through_wall >= past_rim ? Side::Outside : Side::BeyondOpening;
  if (out.side == Side::Outside && at.on_cap) out.side = Side::BeyondOpening;
  return out;
}

}  // namespace evar::geometry
