#include "perspective_projection.hpp"

namespace evar::overlay {

PerspectiveProjection::PerspectiveProjection(const geometry::ProjectionMatrix& P, int width, int height)
    : ViewProjection(width, height), P_(P) {
  (void)geometry::pinhole_camera(P);  // throws for a matrix that is no camera
}

Eigen::Vector2d PerspectiveProjection::project(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d x = P_ * p.homogeneous();
  return x.hnormalized();
}

double PerspectiveProjection::depth(const Eigen::Vector3d& p) const { return geometry::depth_mm(P_, p); }

}  // namespace evar::overlay
