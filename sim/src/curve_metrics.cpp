#include "evar/sim/curve_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace evar::sim {

double distance_to_polyline(const Eigen::Vector2d& p, const std::vector<Eigen::Vector2d>& line) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    const Eigen::Vector2d d = line[i + 1] - line[i];
    const double t = std::clamp((p - line[i]).dot(d) / std::max(d.squaredNorm(), 1e-12), 0.0, 1.0);
    best = std::min(best, (p - line[i] - t * d).norm());
  }
  return best;
}

CurveMatch match_curve(const std::vector<Eigen::Vector2d>& found, const std::vector<Eigen::Vector2d>& truth,
                       const cv::Rect2d& region) {
  CurveMatch m{std::numeric_limits<double>::infinity(), 0.0};
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

}  // namespace evar::sim
