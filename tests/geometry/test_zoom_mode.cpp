// The C-arm's zoom modes (issue 31): a mode's image is a part of the detector in pixels of its
// own, so a point in space lands on the same spot of the detector whichever mode images it;
// the mode's turn and flip compose with the display's into one mapping that puts every field
// pixel where the two in turn put it; and the modes' JSON form with its refusals.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "evar/base/input_error.hpp"
#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/zoom_mode.hpp"
#include "support/error_message.hpp"

using namespace evar;
using geometry::FieldShape;
using geometry::ZoomMode;

namespace {

// A 40 cm flat detector of 1024 elements each way.
const geometry::DetectorSpec kDetector{1024, 1024, 0.390625, 0.390625};

ZoomMode mode(int number, int px, double field_mm) {
  return geometry::centred_zoom_mode(number, std::to_string(static_cast<int>(field_mm / 10)) + " cm", px, px, field_mm / px);
}

// Where a pixel of a view lies on the detector plane, from the central ray (mm).
Eigen::Vector2d on_detector_mm(const Eigen::Vector2d& px, const geometry::DetectorSpec& image, const Eigen::Vector2d& centre) {
  return centre + Eigen::Vector2d((px.x() - 0.5 * (image.cols - 1)) * image.col_spacing_mm,
                                  (px.y() - 0.5 * (image.rows - 1)) * image.row_spacing_mm);
}

}  // namespace

// Modes centred and placed off centre, finer and coarser than the detector: every point of
// a patient-sized box lands, through the mode's projection, on the detector spot the whole
// detector's projection puts it (1e-9 mm).
TEST(ZoomMode, APointLandsOnTheSameSpotOfTheDetectorInEveryMode) {
  std::vector<ZoomMode> modes{mode(1, 1024, 400.0), mode(2, 1024, 300.0), mode(3, 768, 200.0), mode(4, 512, 150.0)};
  modes[2].origin_rows_cols = Eigen::Vector2d(100.0, 300.0);  // off centre: up and to the right
  modes[3].origin_rows_cols = Eigen::Vector2d(600.0, 20.0);   // down and to the left
  const geometry::ProjectionMatrix P_detector =
      geometry::projection_matrix(geometry::view_of(kDetector, 25.0, -10.0, 1200.0, 800.0));
  for (const ZoomMode& m : modes) {
    SCOPED_TRACE(m.name);
    ASSERT_EQ(geometry::zoom_mode_problem(m, kDetector), "");
    const geometry::CArmView v = geometry::zoom_view(kDetector, m, 25.0, -10.0, 1200.0, 800.0);
    EXPECT_EQ(v.detector_cols, m.cols);
    EXPECT_EQ(v.primary_angle_deg, 25.0);
    EXPECT_EQ(v.projection_matrix.has_value(), m.origin_rows_cols.has_value()) << "a centred mode needs no matrix of its own";
    const geometry::ProjectionMatrix P = geometry::projection_matrix(v);
    const Eigen::Vector2d centre = geometry::field_centre_mm(kDetector, m);
    for (double x : {-80.0, 0.0, 60.0})
      for (double y : {-50.0, 40.0})
        for (double z : {-120.0, 0.0, 90.0}) {
          const Eigen::Vector3d X(x, y, z);
          const Eigen::Vector2d full = on_detector_mm(*geometry::project(P_detector, X), kDetector, Eigen::Vector2d::Zero());
          const Eigen::Vector2d here = on_detector_mm(*geometry::project(P, X), geometry::image_detector(m), centre);
          EXPECT_LT((full - here).norm(), 1e-9) << X.transpose();
        }
  }
  // The origin places the field's top-left corner that many elements from the detector's:
  // the top-left pixel's outer corner lies on that element's.
  const ZoomMode& m = modes[2];
  const Eigen::Vector2d corner = on_detector_mm({-0.5, -0.5}, geometry::image_detector(m), geometry::field_centre_mm(kDetector, m));
  const Eigen::Vector2d element = on_detector_mm({300.0 - 0.5, 100.0 - 0.5}, kDetector, Eigen::Vector2d::Zero());
  EXPECT_LT((corner - element).norm(), 1e-9);
}

// Every turn and flip of the mode under every turn and mirror of the display: the one
// composed mapping puts each field pixel where the mode's delivered image and then the
// monitor put it (1e-9 px), and back.
TEST(ZoomMode, TheModesTurnAndFlipComposeWithTheDisplaysIntoOneMapping) {
  for (int r1 : {0, 90, 180, 270})
    for (bool f1 : {false, true})
      for (int r2 : {0, 90, 180, 270})
        for (bool f2 : {false, true}) {
          SCOPED_TRACE("mode " + std::to_string(r1) + (f1 ? " flipped" : "") + ", display " + std::to_string(r2) +
                       (f2 ? " mirrored" : ""));
          ZoomMode m = mode(2, 300, 240.0);
          m.rows = 200;
          m.height_mm = 160.0;
          m.rotation_deg = r1;
          m.horizontal_flip = f1;
          // The image the C-arm delivers (the field turned and flipped), then the monitor's.
          const std::optional<geometry::VideoMapping> delivered = geometry::frame_mapping(std::nullopt, m);
          ASSERT_EQ(delivered.has_value(), r1 != 0 || f1);
          const int delivered_cols = delivered ? delivered->video_cols : m.cols;
          const int delivered_rows = delivered ? delivered->video_rows : m.rows;
          geometry::VideoMapping display;
          display.video_cols = 1280;
          display.video_rows = 1024;
          const bool across = r2 % 180 != 0;
          const double w = across ? delivered_rows : delivered_cols, h = across ? delivered_cols : delivered_rows;
          const double s = 900.0 / std::max(w, h);
          display.image_rect = {100.0, 50.0, w * s, h * s};
          display.rotation_deg = r2;
          display.mirror = f2;
          const std::optional<geometry::VideoMapping> composed = geometry::frame_mapping(display, m);
          ASSERT_TRUE(composed);
          const geometry::VideoToDetector one(*composed, m.cols, m.rows);
          const geometry::VideoToDetector monitor(display, delivered_cols, delivered_rows);
          for (const Eigen::Vector2d& p : {Eigen::Vector2d(0, 0), Eigen::Vector2d(299, 0), Eigen::Vector2d(17.5, 150.25),
                                          Eigen::Vector2d(299, 199)}) {
            const Eigen::Vector2d in_delivered = delivered ? geometry::VideoToDetector(*delivered, m.cols, m.rows).to_video(p) : p;
            const Eigen::Vector2d expected = monitor.to_video(in_delivered);
            EXPECT_LT((one.to_video(p) - expected).norm(), 1e-9) << p.transpose();
            EXPECT_LT((one.to_detector(expected) - p).norm(), 1e-9) << p.transpose();
          }
        }
}

// A round field (an image intensifier's) without a display mapping is still a mapping: the
// whole frame, a circle, so the analysis looks only inside it.
TEST(ZoomMode, ARoundFieldIsACircleOfTheWholeFrame) {
  ZoomMode m = mode(1, 512, 230.0);
  m.shape = FieldShape::Circle;
  const auto mapping = geometry::frame_mapping(std::nullopt, m);
  ASSERT_TRUE(mapping);
  EXPECT_EQ(mapping->field_shape, FieldShape::Circle);
  EXPECT_EQ(mapping->video_cols, 512);
  EXPECT_EQ(mapping->image_rect.width, 512.0);
  const geometry::VideoToDetector map(*mapping, 512, 512);
  EXPECT_LT((map.to_video({10.0, 400.0}) - Eigen::Vector2d(10.0, 400.0)).norm(), 1e-12);
  EXPECT_FALSE(geometry::frame_mapping(std::nullopt, mode(1, 512, 230.0))) << "a plain rectangle needs no mapping";
}

TEST(ZoomMode, TheJsonFormReadsBackAndEveryBadFieldIsNamed) {
  std::vector<ZoomMode> modes{mode(1, 1024, 400.0), mode(7, 512, 150.0)};
  modes[1].origin_rows_cols = Eigen::Vector2d(384.0, 384.0);
  modes[1].rotation_deg = 90;
  modes[1].horizontal_flip = true;
  const nlohmann::json j = geometry::zoom_modes_json(modes);
  const auto back = geometry::parse_zoom_modes(j, kDetector, "node.json");
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[1].number, 7);
  EXPECT_EQ(back[1].name, "15 cm");
  EXPECT_EQ(back[1].rotation_deg, 90);
  EXPECT_TRUE(back[1].horizontal_flip);
  ASSERT_TRUE(back[1].origin_rows_cols);
  EXPECT_EQ(*back[1].origin_rows_cols, Eigen::Vector2d(384.0, 384.0));
  EXPECT_EQ(geometry::find_zoom_mode(back, 7), &back[1]);
  EXPECT_EQ(geometry::find_zoom_mode(back, 2), nullptr);

  const auto refused = [&](nlohmann::json bad) {
    try {
      geometry::parse_zoom_modes(bad, kDetector, "node.json");
    } catch (const base::InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  nlohmann::json twice = j;
  twice[1]["mode"] = 1;
  EXPECT_NE(refused(twice).find("node.json: zoom_modes[1].mode: 1 is given twice"), std::string::npos) << refused(twice);
  nlohmann::json misspelt = j;
  misspelt[0]["field_of_view_rotation"] = 90;
  EXPECT_NE(refused(misspelt).find("zoom_modes[0].field_of_view_rotation: not a field of a zoom mode"), std::string::npos);
  nlohmann::json past = j;
  past[1]["field_of_view_origin_px"] = {900, 0};
  EXPECT_NE(refused(past).find("zoom_modes[1].field_of_view_origin_px: the field placed there"), std::string::npos) << refused(past);
  nlohmann::json sizes = j;
  sizes[0]["field_of_view_dimensions_mm"] = {300, 400};
  EXPECT_NE(refused(sizes).find("zoom_modes[0].field_of_view_dimensions_mm: 300 x 400 mm are 768 x 1024 pixels"), std::string::npos)
      << refused(sizes);
  nlohmann::json shape = j;
  shape[0]["field_of_view_shape"] = "circle";
  EXPECT_NE(refused(shape).find("zoom_modes[0].field_of_view_shape: must be \"RECTANGLE\" or \"ROUND\""), std::string::npos);
  nlohmann::json number = j;
  number[0]["mode"] = 0;
  EXPECT_NE(refused(number).find("zoom_modes[0].mode: must be a whole number 1-255"), std::string::npos);
  EXPECT_NE(refused(nlohmann::json::array()).find("node.json: zoom_modes: expected an array of one or more"), std::string::npos);
}
