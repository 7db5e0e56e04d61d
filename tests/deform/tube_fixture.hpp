#pragma once
// Small synthetic tubes for deform tests (sim's tube sweep, as the vessels are built).
#include <vector>

#include "evar/deform/arap_solver.hpp"
#include "evar/deform/cotangent_weights.hpp"
#include "evar/sim/tube_mesh.hpp"

namespace evar::test {

/// Straight closed tube along +z from z = 0 to `length`, radius `r`.
inline geometry::TriangleMesh straight_tube(double length = 60.0, double r = 8.0, int around = 24,
                                            double spacing = 2.0) {
  const std::vector<Eigen::Vector3d> cl{{0, 0, 0}, {0, 0, length}};
  return sim::tube_mesh(cl, [r](double) { return r; }, {around, spacing, true});
}

inline std::vector<Eigen::Vector3d> straight_centerline(double length = 60.0) {
  std::vector<Eigen::Vector3d> cl;
  for (int k = 0; k <= static_cast<int>(length); ++k) cl.emplace_back(0, 0, k);
  return cl;
}

/// Indices of vertices with z below `lo` or above `hi` (the tube's end rings and caps).
inline std::vector<int> vertices_outside_z(const geometry::TriangleMesh& m, double lo, double hi) {
  std::vector<int> idx;
  for (Eigen::Index i = 0; i < m.V.rows(); ++i)
    if (m.V(i, 2) < lo || m.V(i, 2) > hi) idx.push_back(static_cast<int>(i));
  return idx;
}

inline deform::ArapTerms tube_terms(const geometry::TriangleMesh& m) {
  return deform::mesh_arap_terms(m.V, deform::cotangent_weights(m));
}

}  // namespace evar::test
