#include "fluoro_input.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <vector>

#include "evar/geometry/image_file.hpp"
#include "evar/base/input_error.hpp"
#include "evar/base/input_file.hpp"
#include "evar/geometry/video_frame.hpp"
#include "evar/geometry/xa_dicom.hpp"
#include "view_input.hpp"

namespace evar::app {

FluoroInput load_fluoro(const std::filesystem::path& image, const std::filesystem::path& geometry) {
  FluoroInput in;
  base::check_input_file(image, base::kDicomLimit);  // exists, regular; the tighter limit below
  if (is_dicom_file(image)) {
    auto frame = geometry::read_xa_dicom(image);
    in.image = frame.pixels;
    in.view = frame.view;
  } else {
    cv::Mat raw = geometry::read_image_file(image);
    if (raw.channels() == 3 || raw.channels() == 4) {
      cv::Mat grey;
      cv::cvtColor(raw, grey, raw.channels() == 3 ? cv::COLOR_BGR2GRAY : cv::COLOR_BGRA2GRAY);
      raw = grey;
    }
    if (raw.channels() != 1 || (raw.depth() != CV_8U && raw.depth() != CV_16U))
      throw base::InputError(image.string() + ": expected an 8- or 16-bit grey-level image");
    in.image = raw;
  }
  if (!geometry.empty()) {
    const auto file = read_view_file(geometry);
    in.view = file.view;
    if (const auto& mapping = file.video_mapping) {
      // The monitor's picture: the detector image read back out of its rectangle (turned and
      // mirrored back, resampled to detector pixels), so everything after works on the detector.
      if (mapping->video_cols != in.image.cols || mapping->video_rows != in.image.rows)
        throw base::InputError(geometry.string() + ": video_mapping.video_size_px is " + std::to_string(mapping->video_cols) +
                               " x " + std::to_string(mapping->video_rows) + " but " + image.string() + " is " +
                               std::to_string(in.image.cols) + " x " + std::to_string(in.image.rows));
      const geometry::VideoToDetector map(*mapping, in.view->detector_cols, in.view->detector_rows);
      in.image = geometry::detector_image(in.image, map);
      in.field_mask = geometry::detector_field_mask(*mapping, map);
      in.hidden_mask = geometry::detector_text_mask(*mapping, map);
    }
    if (in.view->detector_cols != in.image.cols || in.view->detector_rows != in.image.rows)
      throw base::InputError(geometry.string() + ": detector_size_px is " + std::to_string(in.view->detector_cols) +
                                 " x " + std::to_string(in.view->detector_rows) + " but " + image.string() + " is " +
                                 std::to_string(in.image.cols) + " x " + std::to_string(in.image.rows));
  }
  return in;
}

cv::Mat device_overlay(const cv::Mat& image, const std::vector<Eigen::Vector2d>& points, bool found) {
  // Displayed on a log scale (like the attenuation the segmentation sees), 1st to 99th
  // percentile stretched, so bone and soft tissue both stay readable.
  cv::Mat f, vis;
  image.convertTo(f, CV_32F);
  cv::log(f + 1.0f, f);
  std::vector<float> v(f.begin<float>(), f.end<float>());
  if (!v.empty()) {
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 100), v.end());
    const float lo = v[v.size() / 100];
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() * 99 / 100), v.end());
    const float hi = v[v.size() * 99 / 100];
    f = (f - lo) * (255.0f / std::max(hi - lo, 1e-6f));
  }
  f.convertTo(vis, CV_8U);
  cv::cvtColor(vis, vis, cv::COLOR_GRAY2BGR);
  const int thickness = std::max(1, image.cols / 512);
  for (std::size_t i = 1; i < points.size(); ++i)
    cv::line(vis, cv::Point2d(points[i - 1].x(), points[i - 1].y()), cv::Point2d(points[i].x(), points[i].y()),
             {0, 200, 255}, thickness, cv::LINE_AA);
  if (!points.empty())
    cv::circle(vis, cv::Point2d(points.front().x(), points.front().y()), 4 * thickness, {0, 0, 255}, thickness, cv::LINE_AA);
  if (!found)
    cv::putText(vis, "no device found", {10, 30 * thickness}, cv::FONT_HERSHEY_SIMPLEX, thickness, {0, 0, 255}, thickness);
  return vis;
}

}  // namespace evar::app
