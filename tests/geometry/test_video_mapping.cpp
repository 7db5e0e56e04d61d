// The display-to-detector mapping (issue 31): checked against the monitor's picture made
// independently with OpenCV (the detector image turned, mirrored and resized into its
// rectangle of the video frame, as a C-arm's display does), its JSON form, and its refusals.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/video_frame.hpp"
#include "evar/geometry/video_mapping.hpp"
#include "geometry/synthetic_fluoro.hpp"
#include "support/error_message.hpp"
#include "support/temp_dir.hpp"
#include "support/video_out.hpp"

using namespace evar;
using geometry::VideoMapping;
using geometry::VideoToDetector;

namespace {

// A detector image with a small Gaussian spot centred at `at` (pixel centres at integers).
cv::Mat detector_with_spot(int cols, int rows, const Eigen::Vector2d& at) {
  cv::Mat image(rows, cols, CV_32F, cv::Scalar(0));
  for (int v = 0; v < rows; ++v)
    for (int u = 0; u < cols; ++u) {
      const double d2 = (u - at.x()) * (u - at.x()) + (v - at.y()) * (v - at.y());
      if (d2 < 100.0) image.at<float>(v, u) = static_cast<float>(std::exp(-d2 / (2.0 * 2.0 * 2.0)));
    }
  return image;
}

Eigen::Vector2d centroid(const cv::Mat& image) {
  const cv::Moments mo = cv::moments(image);
  return {mo.m10 / mo.m00, mo.m01 / mo.m00};
}

}  // namespace

// Every rotation with and without the mirror, a detector larger and smaller than its
// rectangle, pillar-boxed and letter-boxed: a point goes to where the display shows it
// (the spot's centroid in the independently made picture, within a tenth of a pixel) and
// back to itself (1e-9 px).
TEST(VideoMapping, EveryTurnMirrorAndScalePutsAPointWhereTheDisplayShowsItAndBack) {
  struct Frame {
    int detector_cols, detector_rows, video_cols, video_rows;
  };
  for (const Frame& f : {Frame{512, 512, 640, 512}, Frame{400, 300, 960, 540}, Frame{1024, 768, 800, 600}}) {
    for (const int rotation : {0, 90, 180, 270})
      for (const bool mirror : {false, true}) {
        SCOPED_TRACE(std::to_string(f.detector_cols) + "x" + std::to_string(f.detector_rows) + " in " +
                     std::to_string(f.video_cols) + "x" + std::to_string(f.video_rows) + ", rotation " +
                     std::to_string(rotation) + (mirror ? ", mirrored" : ""));
        const bool turned = rotation == 90 || rotation == 270;
        const double shown_w = turned ? f.detector_rows : f.detector_cols, shown_h = turned ? f.detector_cols : f.detector_rows;
        // The largest whole-pixel rectangle of the turned detector's shape, centred.
        const double s = std::min(f.video_cols / shown_w, f.video_rows / shown_h);
        VideoMapping m;
        m.video_cols = f.video_cols;
        m.video_rows = f.video_rows;
        const double w = std::floor(shown_w * s), h = std::floor(shown_h * s);
        m.image_rect = {std::floor((f.video_cols - w) / 2), std::floor((f.video_rows - h) / 2), w, h};
        m.rotation_deg = rotation;
        m.mirror = mirror;
        const VideoToDetector map(m, f.detector_cols, f.detector_rows);
        for (const Eigen::Vector2d& at : {Eigen::Vector2d(40.3, 60.7), Eigen::Vector2d(f.detector_cols - 30.5, 25.25),
                                          Eigen::Vector2d(0.5 * f.detector_cols, f.detector_rows - 20.0)}) {
          const Eigen::Vector2d expected = centroid(test::shown_on_monitor(detector_with_spot(f.detector_cols, f.detector_rows, at), m));
          const Eigen::Vector2d video = map.to_video(at);
          EXPECT_LT((video - expected).norm(), 0.1) << at.transpose() << " -> " << video.transpose() << ", shown at "
                                                    << expected.transpose();
          EXPECT_LT((map.to_detector(video) - at).norm(), 1e-9);
        }
        // The detector's outer corner (its first pixel's outer edge) lands on the rectangle's
        // corner the turn and the mirror take it to.
        const Eigen::Vector2d corner = map.to_video(Eigen::Vector2d(-0.5, -0.5));
        const bool right = (rotation == 90 || rotation == 180) != mirror, bottom = rotation == 180 || rotation == 270;
        EXPECT_NEAR(corner.x(), m.image_rect.x - 0.5 + (right ? w : 0.0), 1e-9);
        EXPECT_NEAR(corner.y(), m.image_rect.y - 0.5 + (bottom ? h : 0.0), 1e-9);
      }
  }
}

TEST(VideoMapping, ItsJsonReadsBackAndSaysWhatIsWrongByField) {
  const test::TempDir dir;
  VideoMapping m;
  m.video_cols = 1280;
  m.video_rows = 1024;
  m.image_rect = {128, 0, 1024, 1024};
  m.mirror = true;
  m.rotation_deg = 90;
  m.field_shape = geometry::FieldShape::Circle;
  m.text_regions = {{0, 0, 120, 40}, {1160, 980, 120, 44}};
  const auto file = dir.path / "mapping.json";
  geometry::write_video_mapping(file, m);
  const VideoMapping back = geometry::read_video_mapping(file);
  EXPECT_EQ(geometry::video_mapping_json(back), geometry::video_mapping_json(m));
  EXPECT_EQ(back.rotation_deg, 90);
  EXPECT_TRUE(back.mirror);
  EXPECT_EQ(back.field_shape, geometry::FieldShape::Circle);
  ASSERT_EQ(back.text_regions.size(), 2u);
  EXPECT_EQ(back.text_regions[1].y, 980);

  // The pinned object's fields only; the optional ones have their neutral values.
  const auto minimal = nlohmann::json::parse(R"({"format": "evarnode-video-mapping", "version": 1,
      "video_size_px": [1920, 1080], "image_rect_px": [420, 0, 1080, 1080]})");
  const VideoMapping plain = geometry::parse_video_mapping(minimal, "node.json", "video_mapping.");
  EXPECT_FALSE(plain.mirror);
  EXPECT_EQ(plain.rotation_deg, 0);
  EXPECT_EQ(plain.field_shape, geometry::FieldShape::Rectangle);
  EXPECT_TRUE(plain.text_regions.empty());

  const auto refusal = [&](const std::string& key, const nlohmann::json& value) {
    nlohmann::json j = minimal;
    j[key] = value;
    return test::error_message([&] { geometry::parse_video_mapping(j, "node.json", "video_mapping."); });
  };
  EXPECT_NE(refusal("mirrored", true).find("node.json: video_mapping.mirrored: not a field of a video mapping"),
            std::string::npos);
  EXPECT_NE(refusal("rotation_deg", 45).find("video_mapping.rotation_deg: must be 0, 90, 180 or 270"), std::string::npos);
  EXPECT_NE(refusal("image_rect_px", {1000, 0, 1080, 1080}).find("video_mapping.image_rect_px: [1000, 0, 1080, 1080] reaches "
                                                                "outside the 1920 x 1080 frame"),
            std::string::npos)
      << refusal("image_rect_px", {1000, 0, 1080, 1080});
  EXPECT_NE(refusal("field_shape", "oval").find("video_mapping.field_shape: must be \"rectangle\""), std::string::npos);
  EXPECT_NE(refusal("text_regions_px", {{0, 0, -5, 10}}).find("text_regions_px[0]: width and height must be positive"),
            std::string::npos);
  EXPECT_NE(refusal("version", 2).find("video_mapping.version: this evarnode reads version 1"), std::string::npos);
  EXPECT_NE(refusal("format", "video").find("video_mapping.format: must be \"evarnode-video-mapping\""), std::string::npos);
  EXPECT_NE(refusal("video_size_px", {1920.5, 1080}).find("video_size_px[0]: must be a whole number"), std::string::npos);
}

// A rectangle of the wrong shape for the turned detector (a mapping written for the other
// rotation) is refused, saying what to check, instead of stretching the roadmap.
TEST(VideoMapping, ARectangleOfAnotherShapeThanTheTurnedDetectorIsRefused) {
  VideoMapping m;
  m.video_cols = 1920;
  m.video_rows = 1080;
  m.image_rect = {240, 0, 1440, 1080};  // 4:3, the 1024 x 768 detector as it is
  EXPECT_NO_THROW(VideoToDetector(m, 1024, 768));
  m.rotation_deg = 90;  // turned, it is 3:4
  const std::string why = test::error_message<std::invalid_argument>([&] { VideoToDetector(m, 1024, 768); });
  EXPECT_NE(why.find("is 1.333 times as wide as high, the 1024 x 768 detector turned by 90 degrees 0.75"), std::string::npos)
      << why;
  EXPECT_NE(why.find("check rotation_deg and the rectangle"), std::string::npos) << why;
}

// The view geometry carries the same object under "video_mapping": written and read back,
// absent when not given, and a bad one refused naming "video_mapping.<field>" or, for a
// rectangle of the wrong shape for this view's detector, the mapping.
TEST(VideoMapping, AViewGeometryCarriesItAndNamesItsFields) {
  const test::TempDir dir;
  geometry::CArmView view;
  view.source_to_detector_mm = 1200;
  view.source_to_isocenter_mm = 800;
  view.detector_cols = view.detector_rows = 1024;
  view.row_spacing_mm = view.col_spacing_mm = 0.3;
  VideoMapping m;
  m.video_cols = 1280;
  m.video_rows = 1024;
  m.image_rect = {128, 0, 1024, 1024};
  m.rotation_deg = 180;
  const auto file = dir.path / "g.json";
  geometry::write_view_geometry(file, view, m);
  const auto back = geometry::read_view_geometry_file(file).video_mapping;
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(geometry::video_mapping_json(*back), geometry::video_mapping_json(m));
  EXPECT_EQ(geometry::read_view_geometry(file).detector_cols, 1024);
  geometry::write_view_geometry(dir.path / "plain.json", view);
  EXPECT_FALSE(geometry::read_view_geometry_file(dir.path / "plain.json").video_mapping.has_value());

  auto j = nlohmann::json::parse(std::ifstream(file));
  j["video_mapping"]["rotation_deg"] = 30;
  std::ofstream(dir.path / "bad.json") << j.dump();
  EXPECT_NE(test::error_message([&] { geometry::read_view_geometry_file(dir.path / "bad.json"); })
                .find("bad.json: video_mapping.rotation_deg: must be 0, 90, 180 or 270"),
            std::string::npos);
  j["video_mapping"]["rotation_deg"] = 0;
  j["video_mapping"]["image_rect_px"] = {0, 0, 1280, 1024};  // 5:4 for a square detector
  std::ofstream(dir.path / "shape.json") << j.dump();
  const std::string why = test::error_message([&] { geometry::read_view_geometry_file(dir.path / "shape.json"); });
  EXPECT_NE(why.find("shape.json: video_mapping: image_rect_px [0, 0, 1280, 1024] is 1.25 times as wide as high"),
            std::string::npos)
      << why;
}

// Fluoroscopy, raw or as a windowed 8-bit display shows it (clipped blacks and whites), is
// never taken for anything else; a blank monitor and a menu over the image are.
TEST(NotFluoroscopy, TellsAMenuOrABlankMonitorFromFluoroscopy) {
  const auto view = evar::test::detector_view(0, 0, 512, 0.6);
  const auto frame = evar::sim::render_fluoro(evar::geometry::projection_matrix(view), view, {evar::test::iliac_guidewire()}, {});
  EXPECT_EQ(evar::geometry::not_fluoroscopy(frame.image), "");
  cv::Mat f, display;
  frame.image.convertTo(f, CV_32F);
  cv::log(f + 1.0f, f);
  // A narrow window, from the 15th to the 85th percentile: much clipped to black and white.
  std::vector<float> v(f.begin<float>(), f.end<float>());
  std::sort(v.begin(), v.end());
  const double lo = v[v.size() * 15 / 100], hi = v[v.size() * 85 / 100];
  f.convertTo(display, CV_8U, 255.0 / (hi - lo), -255.0 * lo / (hi - lo));
  EXPECT_GT(cv::countNonZero(display == 0) + cv::countNonZero(display == 255), display.total() / 10);
  EXPECT_EQ(evar::geometry::not_fluoroscopy(display), "");
  // Limited-range video: black at 16, white at 235.
  cv::Mat limited;
  display.convertTo(limited, CV_8U, 219.0 / 255.0, 16.0);
  EXPECT_EQ(evar::geometry::not_fluoroscopy(limited), "");
  // Raw 14-bit frames with 45 % of the field saturated (direct exposure beside the body).
  cv::Mat raw = frame.image * 4.0;
  raw(cv::Rect(0, raw.rows * 55 / 100, raw.cols, raw.rows - raw.rows * 55 / 100)).setTo(cv::Scalar(16383));
  EXPECT_EQ(evar::geometry::not_fluoroscopy(raw), "");

  const cv::Mat blank(512, 512, CV_8U, cv::Scalar(12));
  EXPECT_NE(evar::geometry::not_fluoroscopy(blank).find("one flat grey"), std::string::npos);
  cv::Mat menu = display.clone();
  menu(cv::Rect(40, 40, 420, 300)).setTo(cv::Scalar(180));
  cv::putText(menu, "PROTOCOL  ABDOMEN", {60, 100}, cv::FONT_HERSHEY_SIMPLEX, 1.0, cv::Scalar(30), 2);
  EXPECT_NE(evar::geometry::not_fluoroscopy(menu).find("a menu or a graphic over the image"), std::string::npos)
      << evar::geometry::not_fluoroscopy(menu);
  // Only the field counts: the same menu outside a field mask is not seen.
  cv::Mat mask(512, 512, CV_8U, cv::Scalar(255));
  mask(cv::Rect(30, 30, 440, 320)).setTo(0);
  EXPECT_EQ(evar::geometry::not_fluoroscopy(menu, mask), "");
}
