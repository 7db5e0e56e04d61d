// The C-arm monitor's picture of a detector image (sim::monitor_picture) read back through
// the same mapping (geometry::detector_image) gives the detector image again, whatever the
// scale, border, turn and mirror; an image intensifier's field is black outside its circle;
// burned-in text lands in its region only.
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "evar/geometry/video_frame.hpp"
#include "evar/sim/monitor_picture.hpp"
#include "support/video_out.hpp"

namespace {

using evar::geometry::FieldShape;
using evar::geometry::PixelRect;
using evar::geometry::VideoMapping;

// Smooth enough to resample (a band-limited pattern and a 6 px wide dark line), not symmetric
// under any turn or mirror.
cv::Mat detector_pattern(int cols, int rows) {
  cv::Mat d(rows, cols, CV_16UC1);
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x)
      d.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(20000 + 60 * x + 25 * y + 3000 * std::sin(x / 9.0) * std::cos(y / 13.0));
  cv::line(d, {cols / 5, rows / 4}, {cols * 3 / 4, rows * 2 / 3}, cv::Scalar(3000), 6, cv::LINE_AA);
  cv::GaussianBlur(d, d, cv::Size(), 1.0);
  return d;
}

VideoMapping mapping(int video_cols, int video_rows, PixelRect rect, int rotation_deg, bool mirror) {
  VideoMapping m;
  m.video_cols = video_cols;
  m.video_rows = video_rows;
  m.image_rect = rect;
  m.rotation_deg = rotation_deg;
  m.mirror = mirror;
  return m;
}

double mean_abs_difference_inside(const cv::Mat& a, const cv::Mat& b, int margin) {
  const cv::Rect inside(margin, margin, a.cols - 2 * margin, a.rows - 2 * margin);
  cv::Mat fa, fb;
  a(inside).convertTo(fa, CV_64F);
  b(inside).convertTo(fb, CV_64F);
  return cv::mean(cv::abs(fa - fb))[0];
}

}  // namespace

TEST(MonitorPicture, ReadBackThroughItsMappingGivesTheDetectorImage) {
  const cv::Mat detector = detector_pattern(200, 160);
  struct Case {
    VideoMapping m;
    const char* what;
  };
  const Case cases[] = {
      {mapping(200, 160, {0, 0, 200, 160}, 0, false), "identity"},
      {mapping(640, 480, {20, 40, 500, 400}, 0, false), "enlarged with borders"},
      {mapping(640, 480, {100, 30, 400, 320}, 0, true), "mirrored"},
      {mapping(640, 480, {120, 40, 320, 400}, 90, false), "turned 90"},
      {mapping(640, 480, {120, 40, 320, 400}, 270, true), "turned 270 and mirrored"},
      {mapping(320, 240, {10, 10, 200, 160}, 180, false), "turned 180"},
      {mapping(160, 120, {20, 10, 80, 100}, 90, true), "shrunk, turned and mirrored"},
  };
  for (const Case& c : cases) {
    const cv::Mat video = evar::sim::monitor_picture(detector, c.m, {});
    ASSERT_EQ(video.cols, c.m.video_cols) << c.what;
    ASSERT_EQ(video.rows, c.m.video_rows) << c.what;
    const evar::geometry::VideoToDetector map(c.m, detector.cols, detector.rows);
    const cv::Mat back = evar::geometry::detector_image(video, map);
    ASSERT_EQ(back.size(), detector.size()) << c.what;
    // Against OpenCV's own turn, flip and resize (independent of the mapping's matrices):
    // the same picture inside the rectangle, less its edge pixels, where the two resamplings
    // treat the border differently. A half-pixel shift of the pattern leaves about 135 grey
    // levels on average here, a turn or mirror the wrong way round thousands.
    const cv::Mat reference = evar::test::shown_on_monitor(detector, c.m);
    const cv::Rect inner(static_cast<int>(c.m.image_rect.x) + 2, static_cast<int>(c.m.image_rect.y) + 2,
                         static_cast<int>(c.m.image_rect.width) - 4, static_cast<int>(c.m.image_rect.height) - 4);
    const double scale = map.video_px_per_detector_px();
    if (scale >= 1.0) {  // OpenCV's resize averages when it shrinks; the monitor picture smooths first
      EXPECT_LT(mean_abs_difference_inside(video(inner), reference(inner), 0), 40.0) << c.what;
    }
    // And read back: the detector image again (resampled twice, bilinear).
    EXPECT_LT(mean_abs_difference_inside(back, detector, 3), scale < 1.0 ? 250.0 : 60.0) << c.what;
    // Black around the image rectangle.
    if (c.m.image_rect.x >= 1) {
      EXPECT_EQ(video.at<std::uint16_t>(video.rows / 2, 0), 0) << c.what;
    }
  }
}

TEST(MonitorPicture, AnImageIntensifiersFieldIsBlackOutsideItsCircleAndTextStaysInItsRegion) {
  const cv::Mat detector = detector_pattern(128, 128);
  VideoMapping m = mapping(400, 300, {100, 20, 256, 256}, 0, false);
  m.field_shape = FieldShape::Circle;
  m.text_regions = {{4, 4, 90, 20}, {4, 270, 90, 20}};
  const cv::Mat video = evar::sim::monitor_picture(detector, m, {"FL 000012", "LAO 35  CAU 15", "left out: no region"});
  // Corners of the rectangle are outside the circle inscribed in it; its centre is inside.
  EXPECT_EQ(video.at<std::uint16_t>(22, 102), 0);
  EXPECT_EQ(video.at<std::uint16_t>(273, 353), 0);
  EXPECT_GT(video.at<std::uint16_t>(148, 228), 0);
  // Text: white pixels in each region, nothing outside the regions and the image.
  const auto white_in = [&](const cv::Rect& r) { return cv::countNonZero(video(r) > 60000); };
  EXPECT_GT(white_in({4, 4, 90, 20}), 20);
  EXPECT_GT(white_in({4, 270, 90, 20}), 20);
  EXPECT_EQ(white_in({0, 100, 100, 100}), 0);
  EXPECT_EQ(white_in({360, 0, 40, 300}), 0);
}
