// Whether a grabbed frame of the C-arm's video output still shows its image where the video
// mapping says (geometry/video_area.hpp, the node's check; finding the area from frames:
// tests/app's calibrate-video tests).
#include <gtest/gtest.h>

#include <algorithm>
#include <opencv2/imgproc.hpp>

#include "evar/geometry/video_area.hpp"

namespace evar::geometry {
namespace {

// A 640 x 512 monitor picture: the image (a textured grey, darker towards one corner, as a
// fluoroscopy image is) in `image`, burned-in text left and right of it, black elsewhere.
cv::Mat monitor_frame(const cv::Rect& image) {
  cv::Mat frame(512, 640, CV_8U, cv::Scalar(0));
  cv::Mat area = frame(image);
  cv::randu(area, cv::Scalar(70), cv::Scalar(200));
  cv::GaussianBlur(area, area, {7, 7}, 2.0);
  for (int r = 0; r < area.rows; ++r)
    for (int c = 0; c < area.cols; ++c)
      area.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(area.at<std::uint8_t>(r, c) * (0.6 + 0.4 * (r + c) / (area.rows + area.cols)));
  cv::putText(frame, "DOE^JOHN", {6, 20}, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(255), 1);
  cv::putText(frame, "LAO 35", {6, 46}, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(255), 1);
  cv::putText(frame, "FL 12", {586, 20}, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(255), 1);
  return frame;
}

VideoMapping mapping(const PixelRect& image_rect) {
  VideoMapping m;
  m.video_cols = 640;
  m.video_rows = 512;
  m.image_rect = image_rect;
  m.text_regions = {{4, 4, 90, 20}, {4, 30, 90, 20}, {584, 4, 52, 20}};
  return m;
}

TEST(VideoMappingMisfit, APictureWhereTheMappingSaysFits) {
  EXPECT_EQ(video_mapping_misfit(monitor_frame({100, 8, 480, 480}), mapping({100, 8, 480, 480})), "");
  // Collimator shutters closed over the picture's edges: less picture, not a wrong mapping.
  cv::Mat shuttered = monitor_frame({100, 8, 480, 480});
  shuttered(cv::Rect(100, 8, 60, 480)).setTo(0);
  shuttered(cv::Rect(100, 8, 480, 40)).setTo(0);
  EXPECT_EQ(video_mapping_misfit(shuttered, mapping({100, 8, 480, 480})), "");
}

// The picture moved on the monitor (or the mapping was made for another layout): image
// content past the mapped rectangle is said, with the side, how far, and both rectangles.
TEST(VideoMappingMisfit, ImageContentPastTheMappedRectangleIsSaidWithTheSideAndHowFar) {
  const cv::Mat frame = monitor_frame({100, 8, 480, 480});
  const std::string left = video_mapping_misfit(frame, mapping({108, 8, 472, 480}));
  EXPECT_NE(left.find("8 px left of the mapping's image rectangle"), std::string::npos) << left;
  EXPECT_NE(left.find("found [100, 8, 480, 480], mapped [108, 8, 472, 480]"), std::string::npos) << left;
  const std::string below = video_mapping_misfit(frame, mapping({100, 0, 480, 470}));
  EXPECT_NE(below.find("18 px below"), std::string::npos) << below;
  // Within the tolerance (3 px by default): the edge's anti-aliasing, not a misfit.
  EXPECT_EQ(video_mapping_misfit(frame, mapping({102, 8, 478, 480})), "");
  EXPECT_NE(video_mapping_misfit(frame, mapping({102, 8, 478, 480}), 1.0), "");
}

// A black frame (the beam off, no picture yet) cannot tell: nothing is said.
TEST(VideoMappingMisfit, ABlackFrameCannotTell) {
  EXPECT_EQ(video_mapping_misfit(cv::Mat(512, 640, CV_8U, cv::Scalar(0)), mapping({100, 8, 480, 480})), "");
  EXPECT_EQ(video_mapping_misfit(cv::Mat(512, 640, CV_16U, cv::Scalar(900)), mapping({100, 8, 480, 480})), "");
}

// Graphics burned into the image itself (a side marker, a scale bar) are found as text: the
// image's content changes from frame to frame, they do not. Frames that do not change (one
// frame given twice) cannot tell, and say they did not look.
TEST(FindVideoArea, GraphicsBurnedIntoTheImageAreTheOnlyThingThatStaysStillAcrossFrames) {
  cv::theRNG().state = 20261207;
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 3; ++k) {
    cv::Mat f = monitor_frame({100, 8, 480, 480});
    cv::putText(f, "R", {520, 60}, cv::FONT_HERSHEY_SIMPLEX, 0.8, cv::Scalar(255), 2);
    cv::line(f, {140, 440}, {240, 440}, cv::Scalar(255), 2);  // a 10 cm scale bar
    frames.push_back(f);
  }
  const VideoArea area = find_video_area(frames);
  EXPECT_TRUE(area.image_text_searched);
  EXPECT_LT(area.still_share, 0.05);
  EXPECT_EQ(area.image_rect.x, 100);
  EXPECT_EQ(area.image_rect.width, 480);
  const auto covers = [&](const cv::Rect& r) {
    return std::any_of(area.text_regions.begin(), area.text_regions.end(), [&](const PixelRect& t) {
      return t.x <= r.x && t.y <= r.y && t.x + t.width >= r.x + r.width && t.y + t.height >= r.y + r.height;
    });
  };
  EXPECT_TRUE(covers({520, 44, 16, 16})) << "the side marker";
  EXPECT_TRUE(covers({140, 439, 101, 3})) << "the scale bar";
  // Outside the image: the three lines of text, as before; on it nothing but the two.
  int on_image = 0;
  for (const PixelRect& t : area.text_regions)
    on_image += t.x >= 100 && t.x + t.width <= 580 && t.y >= 8 && t.y + t.height <= 488;
  EXPECT_EQ(on_image, 2);
  EXPECT_EQ(area.text_regions.size(), 5u);

  const VideoArea frozen = find_video_area({frames[0], frames[0].clone()});
  EXPECT_FALSE(frozen.image_text_searched);
  EXPECT_EQ(frozen.text_regions.size(), 3u);
}

}  // namespace
}  // namespace evar::geometry
