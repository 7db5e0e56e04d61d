#include "evar/geometry/closest_point.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace evar::geometry {

Eigen::Vector3d closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                          const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // Voronoi-region walk (Ericson, Real-Time Collision Detection, 5.1.5).
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return {1, 0, 0};
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double v = d1 / (d1 - d3);
    return {1 - v, v, 0};
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double w = d2 / (d2 - d6);
    return {1 - w, 0, w};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - w, w};
  }
  const double sum = va + vb + vc;
  if (!(sum > 0.0)) return {1, 0, 0};  // degenerate triangle: its first corner
  const double v = vb / sum, w = vc / sum;
  return {1 - v - w, v, w};
}

SurfacePoint closest_point_on_mesh(const TriangleMesh& mesh, const Eigen::Vector3d& p) {
  return closest_points_on_mesh(mesh, {p}).front();
}

std::vector<SurfacePoint> closest_points_on_mesh(const TriangleMesh& mesh, const std::vector<Eigen::Vector3d>& points) {
  std::vector<SurfacePoint> out(points.size());
  for (auto& sp : out) sp.distance_mm = std::numeric_limits<double>::infinity();  // no face: none
  if (points.empty() || mesh.F.rows() == 0) return out;
  // A sphere (centre c, radius rho) around the queries, and for each query the distance to
  // its nearest vertex, which bounds its closest point's. A face can hold an answer only if
  // its first corner lies within rho + the largest such bound + its longest edge of c.
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : points) c += p;
  c /= static_cast<double>(points.size());
  double rho = 0.0, farthest = 0.0;
  std::vector<double> bound(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    rho = std::max(rho, (points[i] - c).norm());
    bound[i] = (mesh.V.row(nearest_vertex(mesh.V, points[i])).transpose() - points[i]).norm();
    farthest = std::max(farthest, bound[i]);
  }
  struct Candidate {
    Eigen::Index face;
    double edge;  // its longest edge from the first corner
  };
  std::vector<Candidate> candidates;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)).transpose();
    const double edge = std::sqrt(std::max((mesh.V.row(mesh.F(f, 1)).transpose() - a).squaredNorm(),
                                           (mesh.V.row(mesh.F(f, 2)).transpose() - a).squaredNorm()));
    const double reach = rho + farthest + edge;
    if ((a - c).squaredNorm() <= reach * reach) candidates.push_back({f, edge});
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d& p = points[i];
    SurfacePoint& best = out[i];
    for (const auto& [f, edge] : candidates) {
      const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)).transpose();
      const double reach = std::min(bound[i], best.distance_mm) + edge;
      if ((p - a).squaredNorm() > reach * reach) continue;
      const Eigen::Vector3d b = mesh.V.row(mesh.F(f, 1)).transpose();
      const Eigen::Vector3d cc = mesh.V.row(mesh.F(f, 2)).transpose();
      const Eigen::Vector3d w = closest_point_on_triangle(p, a, b, cc);
      const Eigen::Vector3d q = w[0] * a + w[1] * b + w[2] * cc;
      const double d = (p - q).norm();
      if (d < best.distance_mm) best = {static_cast<int>(f), w, q, d};
    }
  }
  return out;
}

int nearest_vertex(const geometry::Vertices& V,
                   const Eigen::Vector3d& p) {
  int best = -1;
  double best_d2 = std::numeric_limits<double>::infinity();
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    const double d2 = (V.row(i).transpose() - p).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best = static_cast<int>(i);
    }
  }
  return best;
}

}  // namespace evar::geometry
