#include "evar/deform/landmark_binding.hpp"

#include <Eigen/Geometry>

#include "evar/geometry/closest_point.hpp"

namespace evar::deform {
namespace {
Eigen::Vector3d face_normal(const geometry::Faces& F, const geometry::Vertices& V, int f) {
  const Eigen::Vector3d a = V.row(F(f, 0)).transpose(), b = V.row(F(f, 1)).transpose(), c = V.row(F(f, 2)).transpose();
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double len = n.norm();
  return len > 0.0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
}
}  // namespace

SurfaceBinding bind_to_surface(const geometry::TriangleMesh& mesh, const Eigen::Vector3d& point) {
  const auto sp = geometry::closest_point_on_mesh(mesh, point);
  SurfaceBinding b;
  b.face = sp.face;
  b.barycentric = sp.barycentric;
  b.distance_mm = sp.distance_mm;
  b.normal_offset_mm = (point - sp.point).dot(face_normal(mesh.F, mesh.V, sp.face));
  return b;
}

Eigen::Vector3d evaluate_binding(const SurfaceBinding& b, const geometry::Faces& F, const geometry::Vertices& V) {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int j = 0; j < 3; ++j) p += b.barycentric[j] * V.row(F(b.face, j)).transpose();
  return p + b.normal_offset_mm * face_normal(F, V, b.face);
}

}  // namespace evar::deform
