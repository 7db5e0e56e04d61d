#include "triangle_grid.hpp"

#include <limits>

namespace evar::deform::detail {

TriangleGrid::TriangleGrid(const geometry::TriangleMesh& m, double cell_mm) : m_(m), cell_(cell_mm) {
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

geometry::SurfacePoint TriangleGrid::closest(const Eigen::Vector3d& p) const {
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

Eigen::Vector3i TriangleGrid::index(const Eigen::Vector3d& p) const {
  return ((p - lo_) / cell_).array().floor().cast<int>();
}

std::int64_t TriangleGrid::key(const Eigen::Vector3i& i) {
  return (static_cast<std::int64_t>(i.x() + (1 << 20)) << 42) | (static_cast<std::int64_t>(i.y() + (1 << 20)) << 21) |
         static_cast<std::int64_t>(i.z() + (1 << 20));
}

}  // namespace evar::deform::detail
