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

std::string not_fluoroscopy(const cv::Mat& image, const cv::Mat& field_mask) {
  if (image.channels() != 1 || (image.depth() != CV_8U && image.depth() != CV_16U))
    throw std::invalid_argument("not_fluoroscopy: expected an 8- or 16-bit grey image");
  if (!field_mask.empty() && (field_mask.size() != image.size() || field_mask.type() != CV_8UC1))
    throw std::invalid_argument("not_fluoroscopy: the field mask must be 8-bit, of the image's size");
  cv::Mat values;
  image.convertTo(values, CV_32S);
  // The grey levels' counts over the field (16 bits: 65536 bins).
  std::vector<std::size_t> count(image.depth() == CV_8U ? 256 : 65536, 0);
  std::size_t total = 0;
  for (int y = 0; y < values.rows; ++y) {
    const auto* v = values.ptr<std::int32_t>(y);
    const auto* m = field_mask.empty() ? nullptr : field_mask.ptr<std::uint8_t>(y);
    for (int x = 0; x < values.cols; ++x)
      if (m == nullptr || m[x]) ++count[static_cast<std::size_t>(v[x])], ++total;
  }
  if (total == 0) return "the field shows nothing (the field mask is empty)";
  std::size_t lowest = 0, highest = count.size() - 1;
  while (count[lowest] == 0) ++lowest;
  while (count[highest] == 0) --highest;
  const double full_scale = image.depth() == CV_8U ? 255.0 : 65535.0;
  if (static_cast<double>(highest - lowest) < 0.01 * full_scale)
    return "the image area is one flat grey (" + std::to_string(lowest) + " to " + std::to_string(highest) +
           "): no image on the monitor";
  // Black and full white are where a windowed display clips: not counted.
  std::size_t mode = 1;
  for (std::size_t g = 1; g + 1 < count.size(); ++g)
    if (count[g] > count[mode]) mode = g;
  const double share = static_cast<double>(count[mode]) / static_cast<double>(total);
  if (share > 0.4)
    return std::to_string(static_cast<int>(std::lround(100.0 * share))) + " % of the image area is one grey level (" +
           std::to_string(mode) + "): a menu or a graphic over the image, not fluoroscopy";
  return "";
}

ProjectionMatrix projection_on_video(const ProjectionMatrix& P_detector, const VideoToDetector& map) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();
  A.topRows<2>() = map.detector_to_video();
  return A * P_detector;
}

}  // namespace evar::geometry
