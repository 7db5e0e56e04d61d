#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "device_segmentation_steps.hpp"

namespace evar::geometry::segmentation {

namespace {
constexpr float kInf = std::numeric_limits<float>::infinity();
}

PathEvidence path_evidence(const Ridge& ridge, const cv::Mat& confident, const cv::Rect& inner,
                           const SegmentationOptions& o) {
  PathEvidence e;
  const int H = confident.rows, W = confident.cols;
  const int reach = std::max(3, 2 * static_cast<int>(std::round(0.5 * o.device_width_px)) + 1);
  cv::dilate(ridge.contrast, e.contrast_local, cv::Mat::ones(reach, reach, CV_8U));
  e.side_px = static_cast<float>(1.5 * o.device_width_px);
  e.line_like = cv::Mat(H, W, CV_8U, cv::Scalar(0));
  for (int y = inner.y; y < inner.y + inner.height; ++y)
    for (int x = inner.x; x < inner.x + inner.width; ++x)
      if (confident.at<std::uint8_t>(y, x) && side_step_at(ridge, e, y, x) <= 0.3f * e.contrast_local.at<float>(y, x))
        e.line_like.at<std::uint8_t>(y, x) = 1;
  cv::dilate(e.line_like, e.near_line, cv::Mat::ones(3, 3, CV_8U));
  // The strength of the ridge a path pixel is on: the largest response within the
  // device's width (the path may run a pixel off the centre).
  cv::dilate(ridge.response, e.response_local, cv::Mat::ones(reach, reach, CV_8U));
  return e;
}

float side_step_at(const Ridge& ridge, const PathEvidence& e, int y, int x) {
  const float nx = ridge.nx.at<float>(y, x), ny = ridge.ny.at<float>(y, x), off = ridge.offset.at<float>(y, x);
  const float cx = x + off * nx, cy = y + off * ny;
  return std::abs(bilinear(ridge.attenuation, cx + e.side_px * nx, cy + e.side_px * ny) -
                  bilinear(ridge.attenuation, cx - e.side_px * nx, cy - e.side_px * ny));
}

TipChooser::TipChooser(std::size_t pixels) : score_(pixels, -kInf), running_(pixels, 0.0f), running_contrast_(pixels, 0.0f) {}

// Evidence collected on the way to the root: +1 per pixel on (or next to) a confident
// ridge, −1.5 per other pixel, and −5 per pixel where the path turns by more than 50°
// over 8 px (a wire bends gently; stepping from a bony rim onto it makes a corner).
// A device has the same contrast all along (the attenuation image makes it independent
// of the background), so a pixel counts as ridge only if its response is at least 35 %
// of the running mean along the path so far: a faint bony line met by the path is gap.
// Every score read is written first: parents come first in the order.
int TipChooser::choose(const RidgePaths& paths, const PathEvidence& e, const SegmentationOptions& o) {
  const int W = paths.width();
  const auto ancestor = [&](int q, int k) {
    for (; k > 0 && q >= 0; --k) q = paths.parent(q);
    return q;
  };
  for (const int q : paths.order()) {
    const int y = q / W, x = q % W;
    const int p = paths.parent(q);
    const float r = e.response_local.at<float>(y, x);
    const float c = e.contrast_local.at<float>(y, x);
    const float mean_so_far = p < 0 ? 0.0f : running_[static_cast<std::size_t>(p)];
    const float contrast_so_far = p < 0 ? 0.0f : running_contrast_[static_cast<std::size_t>(p)];
    // The contrast (Δp) too: noise is stronger over bone (fewer quanta), and a chain of
    // noise maxima there can pass on noise units but never has a device's Δp.
    const bool ridge = e.near_line.at<std::uint8_t>(y, x) && r >= 0.35f * mean_so_far && c >= 0.5f * contrast_so_far;
    // Only pixels that pass update the means, so a long faint line cannot drag them down.
    running_[static_cast<std::size_t>(q)] =
        !ridge ? mean_so_far : (mean_so_far == 0.0f ? r : mean_so_far + (r - mean_so_far) / 30.0f);
    running_contrast_[static_cast<std::size_t>(q)] =
        !ridge ? contrast_so_far : (contrast_so_far == 0.0f ? c : contrast_so_far + (c - contrast_so_far) / 30.0f);
    float gain = ridge ? 1.0f : -1.5f;
    if (const int a = ancestor(q, 8); a >= 0)
      if (const int b = ancestor(a, 8); b >= 0) {
        const Eigen::Vector2f v1(x - a % W, y - a / W), v2(a % W - b % W, a / W - b / W);
        if (v1.dot(v2) < std::cos(50.0f * 3.14159265f / 180.0f) * v1.norm() * v2.norm()) gain -= 5.0f;
      }
    score_[static_cast<std::size_t>(q)] = (p < 0 ? 0.0f : score_[static_cast<std::size_t>(p)]) + gain;
  }
  int tip = -1;
  for (const int q : paths.order()) {
    const int y = q / W, x = q % W;
    if (!e.line_like.at<std::uint8_t>(y, x)) continue;
    if (o.seed_px && (Eigen::Vector2d(x, y) - *o.seed_px).norm() > o.seed_radius_px) continue;
    if (tip < 0 || score_[static_cast<std::size_t>(q)] > score_[static_cast<std::size_t>(tip)]) tip = q;
  }
  return tip;
}

}  // namespace evar::geometry::segmentation
