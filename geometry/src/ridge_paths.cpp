#include <algorithm>
#include <bit>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "device_segmentation_steps.hpp"

namespace evar::geometry::segmentation {

namespace {
constexpr float kInf = std::numeric_limits<float>::infinity();
}

RidgePaths::RidgePaths(const Ridge& ridge, const cv::Mat& confident, const cv::Rect& inner, const SegmentationOptions& o,
                       const cv::Mat& searched, const cv::Mat& field)
    : W_(confident.cols), H_(confident.rows), inner_(inner), searched_(searched), field_(field) {
  const cv::Mat& R = ridge.response;
  cv::Mat dist_to_confident;
  cv::Mat not_confident = confident == 0;
  cv::distanceTransform(not_confident, dist_to_confident, cv::DIST_L2, 3);
  // Within the confident band the cost still falls towards the ridge centre, so the path
  // keeps to it instead of wandering across the wire's width.
  const auto cost = [&](int y, int x) {
    const float r = R.at<float>(y, x) / static_cast<float>(o.high_threshold);
    const float miss = 1.0f - std::min(r, 1.0f);
    return 1.0f + 30.0f * miss * miss + 0.5f * (1.0f - std::min(r / 8.0f, 1.0f));
  };
  // The cost of each band pixel, once: the search reads every pixel from each of its eight
  // neighbours. Outside the band the cost is never read.
  band_.assign(static_cast<std::size_t>(H_) * static_cast<std::size_t>(W_), 0);
  band_cost_.assign(band_.size(), 0.0f);
  for (int y = inner.y; y < inner.y + inner.height; ++y)
    for (int x = inner.x; x < inner.x + inner.width; ++x)
      if (dist_to_confident.at<float>(y, x) <= o.gap_radius_px && (searched_.empty() || searched_.at<std::uint8_t>(y, x))) {
        const auto q = static_cast<std::size_t>(y) * static_cast<std::size_t>(W_) + static_cast<std::size_t>(x);
        band_[q] = 1;
        band_cost_[q] = cost(y, x);
      }
  dist_.assign(band_.size(), kInf);
  parent_.assign(dist_.size(), -1);
}

void RidgePaths::push(float d, int q) {
  heap_.push(static_cast<std::uint64_t>(std::bit_cast<std::uint32_t>(d)) << 32 | static_cast<std::uint32_t>(q));
}

bool RidgePaths::seed_border() {
  bool any = false;
  for (int y = inner_.y; y < inner_.y + inner_.height; ++y)
    for (int x = inner_.x; x < inner_.x + inner_.width; ++x) {
      const bool on_border =
          x == inner_.x || y == inner_.y || x == inner_.x + inner_.width - 1 || y == inner_.y + inner_.height - 1 ||
          (!field_.empty() && (!field_.at<std::uint8_t>(y - 1, x) || !field_.at<std::uint8_t>(y + 1, x) ||
                               !field_.at<std::uint8_t>(y, x - 1) || !field_.at<std::uint8_t>(y, x + 1)));
      if (on_border && band_[static_cast<std::size_t>(y * W_ + x)]) {
        dist_[static_cast<std::size_t>(y * W_ + x)] = 0.0f;
        push(0.0f, y * W_ + x);
        any = true;
      }
    }
  return any;
}

void RidgePaths::run_from(int root) {
  dist_[static_cast<std::size_t>(root)] = 0.0f;
  push(0.0f, root);
  run();
}

void RidgePaths::run() {
  order_.clear();
  while (!heap_.empty()) {
    const std::uint64_t top = heap_.top();
    heap_.pop();
    const float d = std::bit_cast<float>(static_cast<std::uint32_t>(top >> 32));
    const int q = static_cast<int>(static_cast<std::uint32_t>(top));
    if (d > dist_[static_cast<std::size_t>(q)]) continue;
    order_.push_back(q);
    const int qy = q / W_, qx = q % W_;
    const float cq = band_cost_[static_cast<std::size_t>(q)];
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        if (!dx && !dy) continue;
        const int ny = qy + dy, nx = qx + dx;
        const auto idx = static_cast<std::size_t>(ny * W_ + nx);
        if (!band_[idx]) continue;
        const float step = (dx && dy) ? 1.41421356f : 1.0f;
        const float nd = d + step * 0.5f * (cq + band_cost_[idx]);
        if (nd < dist_[idx]) {
          dist_[idx] = nd;
          parent_[idx] = q;
          push(nd, ny * W_ + nx);
        }
      }
  }
}

void RidgePaths::reroot(int root) {
  std::fill(dist_.begin(), dist_.end(), kInf);
  std::fill(parent_.begin(), parent_.end(), -1);
  run_from(root);
}

}  // namespace evar::geometry::segmentation
