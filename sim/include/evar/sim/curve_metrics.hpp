#pragma once
// Measures of a found curve against ground truth, for tests and accuracy studies.
#include <Eigen/Core>
#include <vector>

#include <opencv2/core.hpp>

namespace evar::sim {

struct CurveMatch {
  double mean_distance_px;  ///< of the found points to the truth (infinity if fewer than 2)
  double coverage;          ///< share of the truth inside `region` that lies within 2 px of the found curve
};

CurveMatch match_curve(const std::vector<Eigen::Vector2d>& found, const std::vector<Eigen::Vector2d>& truth,
                       const cv::Rect2d& region);

}  // namespace evar::sim
