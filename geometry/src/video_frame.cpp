#include "evar/geometry/video_frame.hpp"

#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace evar::geometry {

cv::Mat detector_image(const cv::Mat& video_frame, const VideoToDetector& map) {
  if (video_frame.cols != map.video_cols() || video_frame.rows != map.video_rows())
    throw std::invalid_argument("video frame " + std::to_string(video_frame.cols) + " x " +
                                std::to_string(video_frame.rows) + " is not the video mapping's " +
                                std::to_string(map.video_cols()) + " x " + std::to_string(map.video_rows()));
  cv::Mat to_video, detector;
  cv::eigen2cv(map.detector_to_video(), to_video);
  // WARP_INVERSE_MAP: the matrix takes each detector pixel to where it lies in the frame.
  cv::warpAffine(video_frame, detector, to_video, cv::Size(map.detector_cols(), map.detector_rows()),
                 cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
  return detector;
}

cv::Mat detector_field_mask(const VideoMapping& mapping, const VideoToDetector& map) {
  const PixelRect& r = mapping.image_rect;
  const double cx = r.x + 0.5 * r.width - 0.5, cy = r.y + 0.5 * r.height - 0.5, radius = 0.5 * std::min(r.width, r.height);
  const auto in = [](const PixelRect& t, const Eigen::Vector2d& v) {
    return v.x() >= t.x - 0.5 && v.x() < t.x + t.width - 0.5 && v.y() >= t.y - 0.5 && v.y() < t.y + t.height - 0.5;
  };
  cv::Mat mask(map.detector_rows(), map.detector_cols(), CV_8U, cv::Scalar(255));
  bool masked = false;
  for (int y = 0; y < mask.rows; ++y)
    for (int x = 0; x < mask.cols; ++x) {
      const Eigen::Vector2d v = map.to_video({x, y});
      bool shown = mapping.field_shape == FieldShape::Rectangle || std::hypot(v.x() - cx, v.y() - cy) <= radius;
      for (const PixelRect& t : mapping.text_regions) shown = shown && !in(t, v);
      if (!shown) {
        mask.at<std::uint8_t>(y, x) = 0;
        masked = true;
      }
    }
  return masked ? mask : cv::Mat();
}

ProjectionMatrix projection_on_video(const ProjectionMatrix& P_detector, const VideoToDetector& map) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();
  A.topRows<2>() = map.detector_to_video();
  return A * P_detector;
}

}  // namespace evar::geometry
