#include "evar/sim/curve_metrics.hpp"

#include "evar/geometry/polyline.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace evar::sim {

CurveMatch match_curve(const std::vector<Eigen::Vector2d>& found, const std::vector<Eigen::Vector2d>& truth,
                       const cv::Rect2d& region) {
  CurveMatch m{std::numeric_limits<double>::infinity(), 0.0};
  if (found.size() < 2) return m;
  double sum = 0.0;
  for (const auto& p : found) sum += geometry::distance_to_polyline_2d(p, truth);
  m.mean_distance_px = sum / static_cast<double>(found.size());
  double inside = 0.0, covered = 0.0;
  for (std::size_t i = 0; i + 1 < truth.size(); ++i) {
    const Eigen::Vector2d mid = 0.5 * (truth[i] + truth[i + 1]);
    if (!region.contains(cv::Point2d(mid.x(), mid.y()))) continue;
    const double len = (truth[i + 1] - truth[i]).norm();
    inside += len;
    if (geometry::distance_to_polyline_2d(mid, found) <= 2.0) covered += len;
  }
  m.coverage = inside > 0.0 ? covered / inside : 0.0;
  return m;
}

}  // namespace evar::sim
