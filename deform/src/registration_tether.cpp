#include "evar/deform/registration_tether.hpp"

#include <Eigen/Geometry>

namespace evar::deform {

ArapTether registration_tether(const geometry::TriangleMesh& mesh, int unknowns, double length_mm) {
  ArapTether tether;
  if (!(length_mm > 0.0)) return tether;
  // Barycentric vertex areas (mm²) over ℓ² (mm²): dimensionless like the cot weights.
  const auto n = mesh.V.rows();
  tether.weight.assign(static_cast<std::size_t>(unknowns), 0.0);
  tether.anchor = geometry::Vertices::Zero(unknowns, 3);
  tether.anchor.topRows(n) = mesh.V;
  const double inv_l2 = 1.0 / (length_mm * length_mm);
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)).transpose(), b = mesh.V.row(mesh.F(f, 1)).transpose(),
                          c = mesh.V.row(mesh.F(f, 2)).transpose();
    const double third = (b - a).cross(c - a).norm() / 6.0;
    for (int j = 0; j < 3; ++j) tether.weight[static_cast<std::size_t>(mesh.F(f, j))] += third * inv_l2;
  }
  return tether;
}

}  // namespace evar::deform
