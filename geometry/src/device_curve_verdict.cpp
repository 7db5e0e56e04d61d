#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "device_segmentation_steps.hpp"
#include "evar/geometry/polyline.hpp"

namespace evar::geometry::segmentation {

namespace {
constexpr float kInf = std::numeric_limits<float>::infinity();
}

void measure_and_judge(std::vector<int> path, bool border_reachable, const Ridge& ridge, const PathEvidence& e,
                       const SegmentationOptions& o, int k, DeviceCurve2D& result) {
  const int W = ridge.response.cols;
  // Judged again against the device's own contrast, now that the path is known (the
  // running means start at the border, which may be past the device's end).
  float device_response = 0.0f, device_contrast = 0.0f;
  {
    std::vector<float> rs, cs;
    for (const int q : path)
      if (e.near_line.at<std::uint8_t>(q / W, q % W)) {
        rs.push_back(e.response_local.at<float>(q / W, q % W));
        cs.push_back(e.contrast_local.at<float>(q / W, q % W));
      }
    if (!rs.empty()) {
      std::nth_element(rs.begin(), rs.begin() + static_cast<long>(rs.size() / 2), rs.end());
      std::nth_element(cs.begin(), cs.begin() + static_cast<long>(cs.size() / 2), cs.end());
      device_response = rs[rs.size() / 2];
      device_contrast = cs[cs.size() / 2];
    }
  }
  const auto ridge_at = [&](int q) {
    const int y = q / W, x = q % W;
    return e.near_line.at<std::uint8_t>(y, x) && e.response_local.at<float>(y, x) >= 0.35f * device_response &&
           e.contrast_local.at<float>(y, x) >= 0.5f * device_contrast;
  };
  // Keep the prefix (from the tip) with the most evidence: past the device's proximal end
  // the path to the border is gap with a few stray ridge pixels.
  std::size_t best_end = 0;
  float running_score = 0.0f, best_score = -kInf;
  for (std::size_t i = 0; i < path.size(); ++i) {
    running_score += ridge_at(path[i]) ? 1.0f : -1.5f;
    if (running_score >= best_score) best_score = running_score, best_end = i;
  }
  result.reaches_border = border_reachable && path.size() - 1 - best_end <= static_cast<std::size_t>(o.device_width_px) + 2;
  path.resize(best_end + 1);
  std::vector<float> contrasts, steps;
  std::vector<Eigen::Vector2d> centres;
  std::vector<float> along;
  int gaps = 0;
  for (const int q : path) {
    const int y = q / W, x = q % W;
    const float off = ridge.offset.at<float>(y, x);
    centres.emplace_back(x + off * ridge.nx.at<float>(y, x), y + off * ridge.ny.at<float>(y, x));
    along.push_back(ridge.response.at<float>(y, x));
    if (ridge_at(q)) {
      contrasts.push_back(e.contrast_local.at<float>(y, x));
      steps.push_back(side_step_at(ridge, e, y, x));
    }
    gaps += ridge_at(q) ? 0 : 1;
  }
  result.points = resample_and_smooth(centres, o.sample_step_px, o.smoothing_px);
  for (std::size_t i = 1; i < result.points.size(); ++i) result.length_px += (result.points[i] - result.points[i - 1]).norm();
  result.gap_fraction = static_cast<double>(gaps) / static_cast<double>(path.size());
  std::nth_element(along.begin(), along.begin() + static_cast<long>(along.size() / 2), along.end());
  result.median_response = along[along.size() / 2];
  result.confidence = (1.0 - result.gap_fraction) * std::min(1.0, result.median_response / o.high_threshold);
  if (!contrasts.empty()) {
    std::nth_element(contrasts.begin(), contrasts.begin() + static_cast<long>(contrasts.size() / 2), contrasts.end());
    result.contrast = contrasts[contrasts.size() / 2];
  }
  if (!steps.empty()) {
    std::nth_element(steps.begin(), steps.begin() + static_cast<long>(steps.size() / 2), steps.end());
    result.side_step = steps[steps.size() / 2];
  }
  // A device is a line on the background: the same background on both sides. The border
  // of a bone or of the body is a step with a rim on it.
  if (result.side_step > 0.3 * result.contrast) {
    result.reason = "the strongest curve is the edge of a wider structure (one side is " +
                    std::to_string(result.side_step) + " −log units denser than the other, the curve itself " +
                    std::to_string(result.contrast) + "): no device in the image";
    result.points.clear();
    return;
  }
  if (result.contrast < o.min_contrast) {
    result.reason = "the strongest curve has a contrast of " + std::to_string(result.contrast) +
                    " (attenuation, −log units), below the " + std::to_string(o.min_contrast) +
                    " of a device: no device in the image";
    result.points.clear();
    return;
  }
  // The measure is in noise units: on a device most of the path is confident (above the
  // high threshold). A chain of noise maxima strung together by the minimal path has only a
  // few confident pixels and a median below it, and is short: the path bridges at most
  // gap_radius_px between confident pixels, so chance alignments rarely run longer than a
  // few such gaps. A weak curve (low dose) is believed only when it is long.
  const double weak_length_px = 4.0 * o.gap_radius_px;
  if (result.median_response < o.high_threshold &&
      (result.median_response < o.low_threshold || result.length_px < weak_length_px)) {
    result.reason = "the strongest curve is only " + std::to_string(result.median_response).substr(0, 4) +
                    " noise units strong along its length and " + std::to_string(static_cast<int>(k * result.length_px)) +
                    " px long (a device is above " + std::to_string(o.high_threshold).substr(0, 4) + ", or above " +
                    std::to_string(o.low_threshold).substr(0, 4) + " over " +
                    std::to_string(static_cast<int>(k * weak_length_px)) + " px): no device in the image";
    result.points.clear();
    return;
  }
  if (result.length_px < o.min_length_px) {
    result.reason = "the strongest curve is " + std::to_string(static_cast<int>(k * result.length_px)) +
                    " px long, shorter than " + std::to_string(static_cast<int>(k * o.min_length_px)) + " px";
    result.points.clear();
    return;
  }
  result.found = true;
}

std::vector<Eigen::Vector2d> resample_and_smooth(const std::vector<Eigen::Vector2d>& pts, double step, double sigma) {
  if (pts.size() < 2) return pts;
  const std::vector<Eigen::Vector2d> even = resample_2d(pts, step);
  const int n = static_cast<int>(even.size());
  if (n < 2) return even;
  const double length = [&] {
    double l = 0.0;
    for (std::size_t i = 1; i < even.size(); ++i) l += (even[i] - even[i - 1]).norm();
    return l;
  }();
  // Gaussian along arc length; the window shrinks symmetrically at the ends, so the tip and
  // the border point are not pulled inwards.
  const double sig = sigma / (length / (n - 1));
  if (!(sig > 0.0)) return even;
  const int half = static_cast<int>(std::ceil(3.0 * sig));
  std::vector<Eigen::Vector2d> out(even.size());
  for (int i = 0; i < n; ++i) {
    const int h = std::min({half, i, n - 1 - i});
    Eigen::Vector2d acc = Eigen::Vector2d::Zero();
    double wsum = 0.0;
    for (int j = -h; j <= h; ++j) {
      const double w = std::exp(-0.5 * j * j / (sig * sig));
      acc += w * even[static_cast<std::size_t>(i + j)];
      wsum += w;
    }
    out[static_cast<std::size_t>(i)] = acc / wsum;
  }
  return out;
}

}  // namespace evar::geometry::segmentation
