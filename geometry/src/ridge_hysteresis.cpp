#include <vector>

#include "device_segmentation_steps.hpp"

namespace evar::geometry::segmentation {

cv::Mat confident_ridge_pixels(const Ridge& ridge, const cv::Rect& inner, const SegmentationOptions& o) {
  const cv::Mat& R = ridge.response;
  const int H = R.rows, W = R.cols;
  // Non-maximum suppression across the ridge.
  cv::Mat ridge_px(H, W, CV_8U, cv::Scalar(0));
  for (int y = inner.y; y < inner.y + inner.height; ++y)
    for (int x = inner.x; x < inner.x + inner.width; ++x) {
      const float v = R.at<float>(y, x);
      if (v < o.low_threshold) continue;
      const float nx = ridge.nx.at<float>(y, x), ny = ridge.ny.at<float>(y, x);
      if (v >= bilinear(R, x + nx, y + ny) && v >= bilinear(R, x - nx, y - ny)) ridge_px.at<std::uint8_t>(y, x) = 1;
    }
  // Hysteresis: the chains of maxima that reach the high threshold somewhere.
  cv::Mat confident(H, W, CV_8U, cv::Scalar(0));
  std::vector<int> stack, component;
  cv::Mat seen(H, W, CV_8U, cv::Scalar(0));
  for (int y = inner.y; y < inner.y + inner.height; ++y)
    for (int x = inner.x; x < inner.x + inner.width; ++x) {
      if (!ridge_px.at<std::uint8_t>(y, x) || seen.at<std::uint8_t>(y, x) || R.at<float>(y, x) < o.high_threshold) continue;
      component.clear();
      stack.assign(1, y * W + x);
      seen.at<std::uint8_t>(y, x) = 1;
      while (!stack.empty()) {
        const int q = stack.back();
        stack.pop_back();
        component.push_back(q);
        const int qy = q / W, qx = q % W;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int ny = qy + dy, nx = qx + dx;
            if (ny < 0 || nx < 0 || ny >= H || nx >= W || seen.at<std::uint8_t>(ny, nx) || !ridge_px.at<std::uint8_t>(ny, nx))
              continue;
            seen.at<std::uint8_t>(ny, nx) = 1;
            stack.push_back(ny * W + nx);
          }
      }
      if (component.size() >= 12)  // chains of noise maxima are shorter
        for (const int q : component) confident.at<std::uint8_t>(q / W, q % W) = 1;
    }
  return confident;
}

}  // namespace evar::geometry::segmentation
