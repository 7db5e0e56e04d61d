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
  // WARP_INVERSE_MAP: the matrix takes each detector pixel to where it lies in the frame;
  // past the frame's edge its edge pixels are repeated (within it, the rectangle's edge is
  // read as the monitor blended it with the border).
  cv::warpAffine(video_frame, detector, to_video, cv::Size(map.detector_cols(), map.detector_rows()),
                 cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
  return detector;
}

namespace {

// 255 where `covered(video pixel)` holds for a detector pixel's centre; empty when nowhere.
template <class Covered>
cv::Mat detector_mask_where(const VideoToDetector& map, const Covered& covered) {
  cv::Mat mask(map.detector_rows(), map.detector_cols(), CV_8U, cv::Scalar(0));
  bool any = false;
  for (int y = 0; y < mask.rows; ++y)
    for (int x = 0; x < mask.cols; ++x)
      if (covered(map.to_video({x, y}))) {
        mask.at<std::uint8_t>(y, x) = 255;
        any = true;
      }
  return any ? mask : cv::Mat();
}

bool inside(const PixelRect& t, const Eigen::Vector2d& v) {
  return v.x() >= t.x - 0.5 && v.x() < t.x + t.width - 0.5 && v.y() >= t.y - 0.5 && v.y() < t.y + t.height - 0.5;
}

}  // namespace

cv::Mat detector_field_mask(const VideoMapping& mapping, const VideoToDetector& map) {
  if (mapping.field_shape == FieldShape::Rectangle) return {};
  const PixelRect& r = mapping.image_rect;
  const double cx = r.x + 0.5 * r.width - 0.5, cy = r.y + 0.5 * r.height - 0.5, radius = 0.5 * std::min(r.width, r.height);
  return detector_mask_where(map, [&](const Eigen::Vector2d& v) { return std::hypot(v.x() - cx, v.y() - cy) <= radius; });
}

cv::Mat detector_text_mask(const VideoMapping& mapping, const VideoToDetector& map) {
  if (mapping.text_regions.empty()) return {};
  return detector_mask_where(map, [&](const Eigen::Vector2d& v) {
    return std::any_of(mapping.text_regions.begin(), mapping.text_regions.end(), [&](const PixelRect& t) { return inside(t, v); });
  });
}

std::string not_fluoroscopy(const cv::Mat& image, const cv::Mat& field_mask) {
  if (image.channels() != 1 || (image.depth() != CV_8U && image.depth() != CV_16U))
    throw std::invalid_argument("not_fluoroscopy: expected an 8- or 16-bit grey image");
  if (!field_mask.empty() && (field_mask.size() != image.size() || field_mask.type() != CV_8UC1))
    throw std::invalid_argument("not_fluoroscopy: the field mask must be 8-bit, of the image's size");
  // The grey levels' counts over the field (16 bits: 65536 bins), read in place.
  std::vector<std::size_t> count(image.depth() == CV_8U ? 256 : 65536, 0);
  std::size_t total = 0;
  const auto tally = [&]<class Pixel>(Pixel) {
    for (int y = 0; y < image.rows; ++y) {
      const auto* v = image.ptr<Pixel>(y);
      const auto* m = field_mask.empty() ? nullptr : field_mask.ptr<std::uint8_t>(y);
      for (int x = 0; x < image.cols; ++x)
        if (m == nullptr || m[x]) ++count[v[x]], ++total;
    }
  };
  if (image.depth() == CV_8U) tally(std::uint8_t{});
  else tally(std::uint16_t{});
  if (total == 0) return "the field shows nothing (the field mask is empty)";
  std::size_t lowest = 0, highest = count.size() - 1;
  while (count[lowest] == 0) ++lowest;
  while (count[highest] == 0) --highest;
  // Flat: within 1 % of the scale the levels reach (8 bits: 255; deeper: the brightest).
  const double scale = image.depth() == CV_8U ? 255.0 : std::max<double>(static_cast<double>(highest), 255.0);
  if (static_cast<double>(highest - lowest) < 0.01 * scale)
    return "the image area is one flat grey (" + std::to_string(lowest) + " to " + std::to_string(highest) +
           "): no image on the monitor";
  // Where a display or a detector clips is not counted: the darkest level present (black, at
  // 0 or at a video pedestal such as 16) and, when it is a whole number of bits' full scale
  // (255, 1023, 4095, 16383, 65535), the brightest (white, saturation). A menu's panel, a
  // dialog's fill, is some other level.
  const bool saturated = highest == 255 || highest == 1023 || highest == 4095 || highest == 16383 || highest == 65535;
  const std::size_t last = saturated ? highest - 1 : highest;
  std::size_t mode = lowest + 1;
  for (std::size_t g = lowest + 1; g <= last; ++g)
    if (count[g] > count[mode]) mode = g;
  const double share = static_cast<double>(count[mode]) / static_cast<double>(total);
  if (mode <= last && share > 0.4)
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
