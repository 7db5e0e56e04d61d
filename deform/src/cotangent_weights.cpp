#include "evar/deform/cotangent_weights.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace evar::deform {
namespace {

// cot of the angle at `o` in the triangle (o, a, b), clamped.
double clamped_cot(const Eigen::Vector3d& o, const Eigen::Vector3d& a, const Eigen::Vector3d& b, double limit) {
  const Eigen::Vector3d u = a - o, v = b - o;
  const double cross = u.cross(v).norm();
  const double dot = u.dot(v);
  const double scale = u.norm() * v.norm();
  // A triangle with (numerically) no area has no defined angles and no area to weight.
  if (!(scale > 0.0) || cross <= 1e-12 * scale) return 0.0;
  return std::clamp(dot / cross, -limit, limit);
}

}  // namespace

std::vector<WeightedEdge> cotangent_weights(const geometry::TriangleMesh& mesh, const CotangentOptions& options) {
  // Half-edge contributions (key = i*nV + j, i<j), then merged.
  struct Contribution {
    long long key;
    double half_cot;
  };
  std::vector<Contribution> contributions;
  contributions.reserve(static_cast<std::size_t>(mesh.F.rows()) * 3);
  const long long n = mesh.V.rows();
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int o = mesh.F(f, k), a = mesh.F(f, (k + 1) % 3), b = mesh.F(f, (k + 2) % 3);
      const double c = clamped_cot(mesh.V.row(o).transpose(), mesh.V.row(a).transpose(),
                                   mesh.V.row(b).transpose(), options.cot_limit);
      const long long i = std::min(a, b), j = std::max(a, b);
      contributions.push_back({i * n + j, 0.5 * c});
    }
  }
  std::sort(contributions.begin(), contributions.end(),
            [](const Contribution& x, const Contribution& y) { return x.key < y.key; });
  std::vector<WeightedEdge> edges;
  edges.reserve(contributions.size() / 2 + 1);
  for (std::size_t s = 0; s < contributions.size();) {
    double w = 0.0;
    std::size_t e = s;
    for (; e < contributions.size() && contributions[e].key == contributions[s].key; ++e) w += contributions[e].half_cot;
    const long long key = contributions[s].key;
    // !(w >= floor) also catches NaN (from overflowing coordinates), which std::max passes on.
    edges.push_back({static_cast<int>(key / n), static_cast<int>(key % n), !(w >= options.w_floor) ? options.w_floor : w});
    s = e;
  }
  return edges;
}

Eigen::SparseMatrix<double> cotangent_laplacian(const geometry::TriangleMesh& mesh, const CotangentOptions& options) {
  const auto edges = cotangent_weights(mesh, options);
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(edges.size() * 4);
  for (const auto& e : edges) {
    t.emplace_back(e.i, e.i, e.w);
    t.emplace_back(e.j, e.j, e.w);
    t.emplace_back(e.i, e.j, -e.w);
    t.emplace_back(e.j, e.i, -e.w);
  }
  Eigen::SparseMatrix<double> L(mesh.V.rows(), mesh.V.rows());
  L.setFromTriplets(t.begin(), t.end());
  return L;
}

}  // namespace evar::deform
