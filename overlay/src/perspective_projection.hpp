#pragma once
// The C-arm's perspective projection as a ViewProjection: a 3x4 matrix P (CT LPS mm →
// homogeneous detector pixels, geometry::projection_matrix composed with the registration),
// so the roadmap lands on the live frame exactly where the C-arm model puts it.
#include "evar/geometry/carm_projection.hpp"
#include "evar/overlay/view_projection.hpp"

namespace evar::overlay {

class PerspectiveProjection final : public ViewProjection {
 public:
  /// P's scale must give points in front of the source positive depth, as
  /// geometry::projection_matrix() does (a matrix times a negative number is the same
  /// projection with every point behind the source). std::invalid_argument when P is not a
  /// finite camera (geometry::pinhole_camera) or a size is not positive.
  PerspectiveProjection(const geometry::ProjectionMatrix& P, int width, int height);

  Eigen::Vector2d project(const Eigen::Vector3d& p_lps) const override;
  /// Distance (mm) from the source along the principal axis (geometry::depth_mm).
  double depth(const Eigen::Vector3d& p_lps) const override;
  /// Points within 1 mm of the source plane (or behind it) are not drawn.
  double near_depth() const override { return 1.0; }

 private:
  geometry::ProjectionMatrix P_;
};

}  // namespace evar::overlay
