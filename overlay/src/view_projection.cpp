#include "evar/overlay/view_projection.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace evar::overlay {

ViewProjection::ViewProjection(int width, int height) : width_(width), height_(height) {
  if (width <= 0 || height <= 0)
    throw std::invalid_argument("ViewProjection: image size must be positive, got " + std::to_string(width) +
                                " x " + std::to_string(height));
}

const char* to_string(StandardView view) {
  switch (view) {
    case StandardView::AP: return "AP";
    case StandardView::Lateral: return "Lateral";
  }
  return "?";
}

ViewAxes view_axes(StandardView view) {
  const Eigen::Vector3d left = Eigen::Vector3d::UnitX(), posterior = Eigen::Vector3d::UnitY(),
                        superior = Eigen::Vector3d::UnitZ();
  switch (view) {
    case StandardView::AP: return {left, -superior, posterior};
    case StandardView::Lateral: return {posterior, -superior, -left};
  }
  throw std::invalid_argument("view_axes: unknown view");
}

OrthographicProjection::OrthographicProjection(const ViewAxes& axes, const Eigen::Vector3d& centre_lps,
                                               double mm_per_pixel, int width, int height)
    : ViewProjection(width, height), axes_(axes), centre_(centre_lps), mm_per_pixel_(mm_per_pixel) {
  constexpr double kTol = 1e-9;
  const bool unit = std::abs(axes.right.norm() - 1.0) < kTol && std::abs(axes.down.norm() - 1.0) < kTol &&
                    std::abs(axes.forward.norm() - 1.0) < kTol;
  if (!unit || std::abs(axes.right.dot(axes.down)) > kTol ||
      (axes.right.cross(axes.down) - axes.forward).norm() > kTol)
    throw std::invalid_argument("OrthographicProjection: axes must be orthonormal with right x down = forward");
  if (!centre_lps.allFinite()) throw std::invalid_argument("OrthographicProjection: centre is not finite");
  if (!(mm_per_pixel > 0.0) || !std::isfinite(mm_per_pixel))
    throw std::invalid_argument("OrthographicProjection: mm_per_pixel must be positive and finite, got " +
                                std::to_string(mm_per_pixel));
}

OrthographicProjection OrthographicProjection::fit(StandardView view, const Eigen::AlignedBox3d& bounds_lps,
                                                   double mm_per_pixel, int width, int height) {
  if (bounds_lps.isEmpty()) throw std::invalid_argument("OrthographicProjection::fit: empty bounds");
  return {view_axes(view), bounds_lps.center(), mm_per_pixel, width, height};
}

Eigen::Vector2d OrthographicProjection::project(const Eigen::Vector3d& p_lps) const {
  const Eigen::Vector3d d = p_lps - centre_;
  return {0.5 * (width() - 1) + d.dot(axes_.right) / mm_per_pixel_,
          0.5 * (height() - 1) + d.dot(axes_.down) / mm_per_pixel_};
}

double OrthographicProjection::depth(const Eigen::Vector3d& p_lps) const {
  return (p_lps - centre_).dot(axes_.forward);
}

Eigen::Vector2d view_extent_mm(StandardView view, const Eigen::AlignedBox3d& bounds_lps) {
  if (bounds_lps.isEmpty()) return Eigen::Vector2d::Zero();
  // Standard view axes are coordinate axes, so the box projects onto its own edges.
  const ViewAxes axes = view_axes(view);
  const Eigen::Vector3d size = bounds_lps.sizes();
  return {size.cwiseProduct(axes.right.cwiseAbs()).sum(), size.cwiseProduct(axes.down.cwiseAbs()).sum()};
}

double fit_mm_per_pixel(const Eigen::AlignedBox3d& bounds_lps, std::span<const StandardView> views, int width,
                        int height, int margin_px) {
  if (bounds_lps.isEmpty()) throw std::invalid_argument("fit_mm_per_pixel: empty bounds");
  if (views.empty()) throw std::invalid_argument("fit_mm_per_pixel: no views");
  const int room_u = width - 2 * margin_px, room_v = height - 2 * margin_px;
  if (room_u <= 0 || room_v <= 0 || margin_px < 0)
    throw std::invalid_argument("fit_mm_per_pixel: no room inside the margins of a " + std::to_string(width) +
                                " x " + std::to_string(height) + " px panel with a " + std::to_string(margin_px) +
                                " px margin");
  double scale = 0.0;
  for (const StandardView view : views) {
    const Eigen::Vector2d extent = view_extent_mm(view, bounds_lps);
    scale = std::max({scale, extent.x() / room_u, extent.y() / room_v});
  }
  return scale > 0.0 ? scale : 1.0;
}

}  // namespace evar::overlay
