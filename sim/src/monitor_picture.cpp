#include "evar/sim/monitor_picture.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace evar::sim {

cv::Mat monitor_picture(const cv::Mat& detector, const geometry::VideoMapping& mapping, const std::vector<std::string>& text) {
  if (detector.type() != CV_16UC1) throw std::invalid_argument("monitor_picture: the detector image must be CV_16UC1");
  const geometry::VideoToDetector map(mapping, detector.cols, detector.rows);
  cv::Mat to_video, video;
  cv::eigen2cv(map.detector_to_video(), to_video);
  // The display scales with area averaging when it shrinks and bilinearly when it enlarges;
  // INTER_AREA is not offered for general affine warps, so a shrink is resampled bilinearly
  // from a copy pre-smoothed to the output's pixel size.
  cv::Mat source = detector;
  const double scale = map.video_px_per_detector_px();
  if (scale < 0.75) {
    const double sigma = 0.5 * std::sqrt(1.0 / (scale * scale) - 1.0);
    cv::GaussianBlur(detector, source, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
  }
  cv::warpAffine(source, video, to_video, cv::Size(mapping.video_cols, mapping.video_rows), cv::INTER_LINEAR,
                 cv::BORDER_CONSTANT, cv::Scalar(0));
  // Pixels whose centre lies outside the rectangle (or its inscribed circle) are black.
  const geometry::PixelRect& r = mapping.image_rect;
  const double cx = r.x + 0.5 * r.width - 0.5, cy = r.y + 0.5 * r.height - 0.5;
  const double radius = 0.5 * std::min(r.width, r.height);
  for (int y = 0; y < video.rows; ++y) {
    auto* row = video.ptr<std::uint16_t>(y);
    for (int x = 0; x < video.cols; ++x) {
      const bool in_rect = x >= r.x - 0.5 && x < r.x + r.width - 0.5 && y >= r.y - 0.5 && y < r.y + r.height - 0.5;
      const bool in_field = mapping.field_shape == geometry::FieldShape::Rectangle ||
                            std::hypot(x - cx, y - cy) <= radius;
      if (!(in_rect && in_field)) row[x] = 0;
    }
  }
  const double white = std::numeric_limits<std::uint16_t>::max();
  for (std::size_t k = 0; k < std::min(text.size(), mapping.text_regions.size()); ++k) {
    const geometry::PixelRect& t = mapping.text_regions[k];
    // The font's height fills most of the region; the text is cut at its edge.
    const double font = std::max(0.2, 0.7 * t.height / 22.0);
    const cv::Rect box(static_cast<int>(t.x), static_cast<int>(t.y), static_cast<int>(t.width), static_cast<int>(t.height));
    cv::Mat region = video(box & cv::Rect(0, 0, video.cols, video.rows));
    cv::putText(region, text[k], cv::Point(2, static_cast<int>(0.8 * t.height)), cv::FONT_HERSHEY_SIMPLEX, font,
                cv::Scalar(white), std::max(1, static_cast<int>(std::lround(font * 1.5))), cv::LINE_AA);
  }
  return video;
}

}  // namespace evar::sim
