#pragma once
// Rendered test frames of known wires (sim::render_fluoro) and the measures the
// segmentation and reconstruction tests assert on.
#include <cmath>
#include <vector>

#include "evar/geometry/carm_projection.hpp"
#include "evar/sim/fluoro_render.hpp"

namespace evar::test {

/// A 0.3 mm, 1024 x 1024 detector (the accuracy case), SID 1200, SOD 800.
inline geometry::CArmView detector_view(double primary_deg, double secondary_deg, int size_px = 1024, double spacing_mm = 0.3) {
  geometry::CArmView v;
  v.primary_angle_deg = primary_deg;
  v.secondary_angle_deg = secondary_deg;
  v.source_to_detector_mm = 1200;
  v.source_to_isocenter_mm = 800;
  v.detector_cols = size_px;
  v.detector_rows = size_px;
  v.row_spacing_mm = v.col_spacing_mm = spacing_mm;
  return v;
}

/// A guidewire up the right iliac into the aneurysm sac (world mm, isocenter at the sac),
/// tip first, bending in depth as well as sideways.
inline geometry::Polyline iliac_guidewire(double shift_x = 0.0) {
  geometry::Polyline w;
  for (int k = 60; k >= 0; --k) {
    const double s = k / 60.0;
    w.emplace_back(shift_x - 40.0 + 45.0 * s + 8.0 * std::sin(3.0 * s), 12.0 * std::sin(2.0 * s) - 5.0, -150.0 + 200.0 * s);
  }
  return w;
}

/// Expected shadow width (px) of a wire of `diameter_mm` at the isocenter.
inline double shadow_width_px(const geometry::CArmView& v, double diameter_mm = 0.89) {
  return diameter_mm * v.source_to_detector_mm / v.source_to_isocenter_mm / v.col_spacing_mm;
}

inline double distance_to_polyline(const Eigen::Vector2d& p, const std::vector<Eigen::Vector2d>& line) {
  double best = INFINITY;
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    const Eigen::Vector2d d = line[i + 1] - line[i];
    const double t = std::clamp((p - line[i]).dot(d) / std::max(d.squaredNorm(), 1e-12), 0.0, 1.0);
    best = std::min(best, (p - line[i] - t * d).norm());
  }
  return best;
}

struct CurveMatch {
  double mean_distance_px = INFINITY;  ///< of the found points to the truth
  double coverage = 0.0;               ///< share of the truth (inside `region`) within 2 px of the found curve
};

inline CurveMatch match(const std::vector<Eigen::Vector2d>& found, const std::vector<Eigen::Vector2d>& truth,
                        const cv::Rect2d& region) {
  CurveMatch m;
  if (found.size() < 2) return m;
  double sum = 0.0;
  for (const auto& p : found) sum += distance_to_polyline(p, truth);
  m.mean_distance_px = sum / static_cast<double>(found.size());
  double inside = 0.0, covered = 0.0;
  for (std::size_t i = 0; i + 1 < truth.size(); ++i) {
    const Eigen::Vector2d mid = 0.5 * (truth[i] + truth[i + 1]);
    if (!region.contains(cv::Point2d(mid.x(), mid.y()))) continue;
    const double len = (truth[i + 1] - truth[i]).norm();
    inside += len;
    if (distance_to_polyline(mid, found) <= 2.0) covered += len;
  }
  m.coverage = inside > 0.0 ? covered / inside : 0.0;
  return m;
}

}  // namespace evar::test
