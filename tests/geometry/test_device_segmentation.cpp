#include <gtest/gtest.h>

#include <algorithm>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cstdlib>

#include "evar/geometry/device_segmentation.hpp"
#include "synthetic_fluoro.hpp"

using namespace evar;
using geometry::SegmentationOptions;

namespace {

struct Case {
  geometry::CArmView view = test::detector_view(30, 10);
  sim::FluoroOptions render;
  std::vector<geometry::Polyline> wires{test::iliac_guidewire()};
};

struct Outcome {
  sim::FluoroFrame frame;
  geometry::DeviceCurve2D found;
  test::CurveMatch match;
};

Outcome run(const Case& c, SegmentationOptions so = {}) {
  Outcome o;
  o.frame = sim::render_fluoro(geometry::projection_matrix(c.view), c.view, c.wires, c.render);
  so.device_width_px = test::shadow_width_px(c.view);
  o.found = geometry::segment_device(o.frame.image, so);
  // The searched region: the exposed field less the rim the ridge filter cannot see into.
  const double rim = 3.0 * so.device_width_px;
  const cv::Rect2d region(o.found.field.x + rim, o.found.field.y + rim, o.found.field.width - 2 * rim,
                          o.found.field.height - 2 * rim);
  o.match = test::match(o.found.points, o.frame.truth.front(), region);
  // EVAR_TEST_PICTURES=dir: the frame with the truth (green) and the result (red).
  if (const char* dir = std::getenv("EVAR_TEST_PICTURES")) {
    cv::Mat f, vis;
    o.frame.image.convertTo(f, CV_32F);
    cv::log(f + 1.0f, f);
    cv::normalize(f, f, 0, 255, cv::NORM_MINMAX);
    f.convertTo(vis, CV_8U);
    cv::cvtColor(vis, vis, cv::COLOR_GRAY2BGR);
    for (const auto& t : o.frame.truth.front())
      if (t.x() >= 0 && t.y() >= 0 && t.x() < vis.cols && t.y() < vis.rows) vis.at<cv::Vec3b>(int(t.y()), int(t.x())) = {0, 255, 0};
    for (std::size_t i = 1; i < o.found.points.size(); ++i)
      cv::line(vis, cv::Point2d(o.found.points[i - 1].x(), o.found.points[i - 1].y()),
               cv::Point2d(o.found.points[i].x(), o.found.points[i].y()), {0, 0, 255}, 1);
    cv::imwrite(std::string(dir) + "/" + ::testing::UnitTest::GetInstance()->current_test_info()->name() + ".png", vis);
  }
  return o;
}

// Mean of (found point − its nearest point on the truth): a systematic shift of the
// whole curve (a pixel-centre convention off by half a pixel) shows here even when the
// mean distance stays small.
Eigen::Vector2d mean_offset_px(const std::vector<Eigen::Vector2d>& found, const std::vector<Eigen::Vector2d>& truth) {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (const auto& p : found) {
    Eigen::Vector2d nearest = truth.front();
    for (std::size_t i = 1; i < truth.size(); ++i) {
      const Eigen::Vector2d a = truth[i - 1], d = truth[i] - a;
      const double t = d.squaredNorm() > 0 ? std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
      if ((a + t * d - p).squaredNorm() < (nearest - p).squaredNorm()) nearest = a + t * d;
    }
    sum += p - nearest;
  }
  return sum / static_cast<double>(found.size());
}

}  // namespace

// Tolerances are the issue's: mean distance to the true centreline under 1 px, more than
// 90 % of the visible wire found; and, so a half-pixel convention slip cannot hide in
// them, the measured accuracy (0.05 px here) held to 0.25 px with no shift over 0.1 px.
TEST(DeviceSegmentation, FindsAGuidewireOverSpineAndSoftTissueToSubPixelAccuracy) {
  const auto o = run({});
  ASSERT_TRUE(o.found.found) << o.found.reason;
  EXPECT_LT(o.match.mean_distance_px, 1.0);
  EXPECT_LT(o.match.mean_distance_px, 0.25);
  EXPECT_LT(mean_offset_px(o.found.points, o.frame.truth.front()).norm(), 0.1);
  EXPECT_GT(o.match.coverage, 0.9);
  EXPECT_TRUE(o.found.reaches_border);
  EXPECT_GT(o.found.confidence, 0.8);
  // Tip first: the first point is the wire's distal end (the truth runs tip first too).
  EXPECT_LT((o.found.points.front() - o.frame.truth.front().front()).norm(), 5.0);
}

// A wire whose tip lies outside the field (the table moved on to the bifurcation) enters and
// leaves through the border: found from border to border, not from its middle to one side.
TEST(DeviceSegmentation, FindsAWireThatCrossesTheWholeField) {
  const Case c;
  const auto frame = sim::render_fluoro(geometry::projection_matrix(c.view), c.view, c.wires, c.render);
  const auto& truth = frame.truth.front();
  // The band of rows between the tip and the far end, so both ends are cut off.
  double top = 1e9, bottom = -1e9;
  for (const auto& p : truth) top = std::min(top, p.y()), bottom = std::max(bottom, p.y());
  const int y0 = static_cast<int>(top + 0.25 * (bottom - top)), y1 = static_cast<int>(top + 0.75 * (bottom - top));
  const cv::Mat band = frame.image.rowRange(y0, y1).clone();
  std::vector<Eigen::Vector2d> shifted;
  for (const auto& p : truth) shifted.emplace_back(p.x(), p.y() - y0);
  SegmentationOptions so;
  so.device_width_px = test::shadow_width_px(c.view);
  const auto found = geometry::segment_device(band, so);
  ASSERT_TRUE(found.found) << found.reason;
  const double rim = 3.0 * so.device_width_px;
  const auto m = test::match(found.points, shifted, cv::Rect2d(rim, rim, band.cols - 2 * rim, band.rows - 2 * rim));
  EXPECT_GT(m.coverage, 0.9);
  EXPECT_LT(m.mean_distance_px, 1.0);
}

TEST(DeviceSegmentation, CopesWithLowDoseAndCollimation) {
  Case c;
  c.view = test::detector_view(-25, -15);
  c.render.photons_per_pixel = 400;  // about an eighth of the default dose
  c.render.collimation_px = 90;
  c.render.seed = 7;
  c.wires = {test::iliac_guidewire(-30.0)};
  const auto o = run(c);
  ASSERT_TRUE(o.found.found) << o.found.reason;
  EXPECT_LT(o.match.mean_distance_px, 1.0);
  EXPECT_GT(o.match.coverage, 0.9);
  EXPECT_NEAR(o.found.field.x, 90, 2);  // the shutters were found
  EXPECT_NEAR(o.found.field.width, 1024 - 180, 4);
}

TEST(DeviceSegmentation, LargeFieldOverSpineAndPelvisWithAThinShadow) {
  Case c;
  c.view = test::detector_view(10, -5, 1024, 0.6);  // the whole abdomen and pelvis, 2.2 px wide shadow
  c.render.seed = 11;
  c.wires = {test::iliac_guidewire(-20.0)};
  const auto o = run(c);
  ASSERT_TRUE(o.found.found) << o.found.reason;
  EXPECT_LT(o.match.mean_distance_px, 1.0);
  EXPECT_GT(o.match.coverage, 0.9);
  EXPECT_FALSE(o.found.reaches_border);  // this wire ends over the pelvis, inside the field
}

TEST(DeviceSegmentation, AWireLeavingTheDetectorEndsAtTheBorder) {
  Case c;
  c.wires = {test::iliac_guidewire(60.0)};  // far to the patient's left: runs off the side
  const auto o = run(c);
  ASSERT_TRUE(o.found.found) << o.found.reason;
  EXPECT_LT(o.match.mean_distance_px, 1.0);
  EXPECT_GT(o.match.coverage, 0.9);
  EXPECT_TRUE(o.found.reaches_border);
}

TEST(DeviceSegmentation, ASeedChoosesBetweenTwoDevices) {
  Case c;
  c.wires = {test::iliac_guidewire(), test::iliac_guidewire(-45.0)};
  const auto frame = sim::render_fluoro(geometry::projection_matrix(c.view), c.view, c.wires, c.render);
  SegmentationOptions so;
  so.device_width_px = test::shadow_width_px(c.view);
  for (std::size_t which = 0; which < 2; ++which) {
    so.seed_px = frame.truth[which].front() + Eigen::Vector2d(3, -2);  // a click near the tip
    const auto found = geometry::segment_device(frame.image, so);
    ASSERT_TRUE(found.found) << found.reason;
    const auto m = test::match(found.points, frame.truth[which], cv::Rect2d(20, 20, 984, 984));
    EXPECT_LT(m.mean_distance_px, 1.0) << "wire " << which;
    EXPECT_GT(m.coverage, 0.9) << "wire " << which;
  }
}

TEST(DeviceSegmentation, ACrossingDeviceDoesNotDerailThePath) {
  Case c;
  // A second, short straight wire crossing the guidewire about half way along it.
  geometry::Polyline crossing{{-45.0, -5.0, -40.0}, {25.0, 5.0, -20.0}};
  c.wires = {test::iliac_guidewire(), crossing};
  const auto o = run(c);
  ASSERT_TRUE(o.found.found) << o.found.reason;
  EXPECT_LT(o.match.mean_distance_px, 1.0);  // no detour along the other wire
  EXPECT_GT(o.match.coverage, 0.9);          // and straight on through the crossing
}

TEST(DeviceSegmentation, EightBitInputWorksToo) {
  const Case c;
  auto frame = sim::render_fluoro(geometry::projection_matrix(c.view), c.view, c.wires, c.render);
  cv::Mat eight;
  frame.image.convertTo(eight, CV_8U, 255.0 / 4095.0);
  SegmentationOptions so;
  so.device_width_px = test::shadow_width_px(c.view);
  const auto found = geometry::segment_device(eight, so);
  ASSERT_TRUE(found.found) << found.reason;
  EXPECT_LT(test::match(found.points, frame.truth.front(), cv::Rect2d(20, 20, 984, 984)).mean_distance_px, 1.0);
}

// A frame grabber on the C-arm's video output sees the processed display: log, windowed
// (1-99 % here), 8 bits, its darkest anatomy clipped to black. Before the fix the
// ragged edge of the clipped region outshone the wire (a fifth of it found, the tip
// placed 700 px away, on a frame like this from a simulated session).
TEST(DeviceSegmentation, AnEightBitDisplayWithClippedBlacksStillShowsTheWire) {
  const Case c;
  const auto frame = sim::render_fluoro(geometry::projection_matrix(c.view), c.view, c.wires, c.render);
  cv::Mat L;
  frame.image.convertTo(L, CV_32F);
  cv::max(L, 1.0, L);
  cv::log(L, L);
  std::vector<float> sorted(L.begin<float>(), L.end<float>());
  std::sort(sorted.begin(), sorted.end());
  const float lo = sorted[sorted.size() / 100], hi = sorted[sorted.size() * 99 / 100];
  cv::Mat display;
  L.convertTo(display, CV_8U, 255.0 / (hi - lo), -255.0 * lo / (hi - lo));  // saturating: the clip
  ASSERT_GT(cv::countNonZero(display == 0), display.total() / 200) << "no clipped blacks to test with";
  SegmentationOptions so;
  so.device_width_px = test::shadow_width_px(c.view);
  so.min_contrast = 0.0;  // a display's grey levels are not −log units (docs/FORMATS.md)
  const auto found = geometry::segment_device(display, so);
  ASSERT_TRUE(found.found) << found.reason;
  const double rim = 3.0 * so.device_width_px;
  const auto m = test::match(found.points, frame.truth.front(),
                             cv::Rect2d(found.field.x + rim, found.field.y + rim, found.field.width - 2 * rim,
                                        found.field.height - 2 * rim));
  EXPECT_GT(m.coverage, 0.9);
  EXPECT_LT(m.mean_distance_px, 1.0);
  EXPECT_LT((found.points.front() - frame.truth.front().front()).norm(), 5.0);  // tip first
}

TEST(DeviceSegmentation, SaysClearlyWhenThereIsNothing) {
  const Case c;
  const auto frame = sim::render_fluoro(geometry::projection_matrix(c.view), c.view, {}, c.render);
  SegmentationOptions so;
  so.device_width_px = test::shadow_width_px(c.view);
  const auto none = geometry::segment_device(frame.image, so);
  EXPECT_FALSE(none.found);
  EXPECT_FALSE(none.reason.empty());
  EXPECT_TRUE(none.points.empty());

  const auto dark = geometry::segment_device(cv::Mat(256, 256, CV_16UC1, cv::Scalar(0)));
  EXPECT_FALSE(dark.found);
  EXPECT_NE(dark.reason.find("no exposed field"), std::string::npos) << dark.reason;

  cv::Mat flat(256, 256, CV_8UC1, cv::Scalar(128));
  EXPECT_FALSE(geometry::segment_device(flat).found);
}

// The device/no-device decision over many noise draws and views: frames without a wire
// must never report one (a false device would be reconstructed and bend the vessels), and
// the same frames with the wire must always find it.
TEST(DeviceSegmentation, DecidesDeviceOrNoneOverManyFrames) {
  int false_devices = 0, missed = 0;
  std::string first_false, first_miss;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const auto view = test::detector_view(30.0 + 7.0 * static_cast<double>(seed), 10.0 - static_cast<double>(seed));
    sim::FluoroOptions render;
    render.seed = seed;
    SegmentationOptions so;
    so.device_width_px = test::shadow_width_px(view);
    const auto P = geometry::projection_matrix(view);
    const auto empty = geometry::segment_device(sim::render_fluoro(P, view, {}, render).image, so);
    if (empty.found) {
      ++false_devices;
      if (first_false.empty())
        first_false = "seed " + std::to_string(seed) + ": " + std::to_string(empty.length_px) + " px, response " +
                      std::to_string(empty.median_response);
    } else {
      EXPECT_FALSE(empty.reason.empty());
    }
    const auto wire = geometry::segment_device(sim::render_fluoro(P, view, {sim::iliac_guidewire()}, render).image, so);
    missed += wire.found ? 0 : 1;
    if (!wire.found && first_miss.empty()) first_miss = "seed " + std::to_string(seed) + ": " + wire.reason;
    if (seed <= 5) {
      // A third of the default dose (docs/ACCURACY.md has lower doses, where the wire breaks up).
      render.photons_per_pixel = 1000;
      const auto faint = geometry::segment_device(sim::render_fluoro(P, view, {sim::iliac_guidewire()}, render).image, so);
      missed += faint.found ? 0 : 1;
      if (!faint.found && first_miss.empty()) first_miss = "seed " + std::to_string(seed) + " at low dose: " + faint.reason;
    }
  }
  EXPECT_EQ(false_devices, 0) << first_false;
  EXPECT_EQ(missed, 0) << first_miss;
}

TEST(DeviceSegmentation, GarbageNeverCrashes) {
  cv::Mat noise(300, 200, CV_32FC1);
  cv::randu(noise, -1e6, 1e6);
  noise.at<float>(10, 10) = std::numeric_limits<float>::quiet_NaN();
  noise.at<float>(20, 10) = std::numeric_limits<float>::infinity();
  EXPECT_NO_THROW(geometry::segment_device(noise));
  EXPECT_NO_THROW(geometry::segment_device(cv::Mat(3, 3, CV_8UC1, cv::Scalar(9))));
  EXPECT_THROW(geometry::segment_device(cv::Mat()), std::invalid_argument);
  EXPECT_THROW(geometry::segment_device(cv::Mat(10, 10, CV_8UC3)), std::invalid_argument);
}

// Options that would start the path search outside its band (an independent review found
// a read before the image with a zero threshold and a negative gap radius) are refused.
TEST(DeviceSegmentation, OptionsThatLeaveNoBandAreRefused) {
  const cv::Mat flat(72, 46, CV_32FC1, cv::Scalar(1000.0f));
  geometry::SegmentationOptions o;
  o.high_threshold = 0.0;
  EXPECT_THROW(geometry::segment_device(flat, o), std::invalid_argument);
  o = {};
  o.low_threshold = -1.0;
  EXPECT_THROW(geometry::segment_device(flat, o), std::invalid_argument);
  o = {};
  o.low_threshold = 2.0 * o.high_threshold;
  EXPECT_THROW(geometry::segment_device(flat, o), std::invalid_argument);
  o = {};
  o.gap_radius_px = -1.0;
  EXPECT_THROW(geometry::segment_device(flat, o), std::invalid_argument);
  o.gap_radius_px = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(geometry::segment_device(flat, o), std::invalid_argument);
  EXPECT_NO_THROW(geometry::segment_device(flat, {}));
}

// A field that is not a rectangle (an image intensifier's circle read out of a video-out
// frame, black around it) and graphics over the image (a ruler burned in): with the field
// mask the wire is found inside the circle up to its edge, and nothing in the masked parts;
// without it the circle's black edge and the ruler are there to be taken for a device.
TEST(DeviceSegmentation, AFieldMaskKeepsTheSearchInsideACircleAndOffBurnedInGraphics) {
  const Case c;
  const auto frame = sim::render_fluoro(geometry::projection_matrix(c.view), c.view, c.wires, c.render);
  const cv::Point centre(frame.image.cols / 2, frame.image.rows / 2);
  const int radius = frame.image.cols * 45 / 100;
  cv::Mat field(frame.image.size(), CV_8U, cv::Scalar(0));
  cv::circle(field, centre, radius, cv::Scalar(255), cv::FILLED);
  const Eigen::Vector2d tip = frame.truth.front().front();
  const Eigen::Vector2d along = (tip - frame.truth.front()[20]).normalized();
  // A cross-hair burned into the image, lined up with the wire beyond its tip (a dark line as
  // wide as the wire, 20 px short of the tip): wholly inside the circle, and reaching out of it
  // (its box then notches the circle's edge, and is still no way out of the field).
  for (const double length : {120.0, 260.0}) {
    SCOPED_TRACE(length > 200 ? "the cross-hair reaches out of the circle" : "the cross-hair inside the circle");
    cv::Mat image = frame.image.clone();
    image.setTo(0, field == 0);
    const Eigen::Vector2d from = tip + 20.0 * along, to = tip + (20.0 + length) * along;
    cv::line(image, cv::Point2d(from.x(), from.y()), cv::Point2d(to.x(), to.y()), cv::Scalar(5), 4, cv::LINE_AA);
    const cv::Rect ruler = cv::Rect(cv::Point2d(std::min(from.x(), to.x()) - 6, std::min(from.y(), to.y()) - 6),
                                    cv::Point2d(std::max(from.x(), to.x()) + 7, std::max(from.y(), to.y()) + 7)) &
                           cv::Rect(0, 0, image.cols, image.rows);
    cv::Mat hidden(image.size(), CV_8U, cv::Scalar(0));
    hidden(ruler).setTo(255);
    SegmentationOptions so;
    so.device_width_px = test::shadow_width_px(c.view);
    {
      const auto f = geometry::segment_device(image, so);
      ASSERT_TRUE(f.found) << f.reason;
      EXPECT_GT((f.points.front() - tip).norm(), 50.0) << "without the masks the cross-hair is taken for the wire's end";
    }
    so.field_mask = field;
    so.hidden_mask = hidden;
    const auto found = geometry::segment_device(image, so);
    ASSERT_TRUE(found.found) << found.reason;
    for (const auto& p : found.points) {
      ASSERT_LT(std::hypot(p.x() - centre.x, p.y() - centre.y), radius) << "a point outside the circle";
      ASSERT_FALSE(ruler.contains(cv::Point(static_cast<int>(p.x()), static_cast<int>(p.y())))) << "a point on the ruler";
    }
    // The wire inside the circle, clear of its rim, is found.
    std::vector<Eigen::Vector2d> inside;
    const double rim = 3.0 * so.device_width_px;
    for (const auto& t : frame.truth.front())
      if (std::hypot(t.x() - centre.x, t.y() - centre.y) < radius - rim && !ruler.contains(cv::Point(t.x(), t.y())))
        inside.push_back(t);
    ASSERT_GT(inside.size(), 100u);
    const auto m = test::match(found.points, inside, cv::Rect2d(0, 0, image.cols, image.rows));
    EXPECT_LT(m.mean_distance_px, 1.0);
    EXPECT_TRUE(found.reaches_border) << "the wire leaves the field at the circle's edge";
    // Its tip is the wire's, up to the rim kept clear of the cross-hair's box.
    EXPECT_LT((found.points.front() - tip).norm(), 0.5 * rim + 2.0) << found.points.front().transpose();
  }
  SegmentationOptions so;
  so.device_width_px = test::shadow_width_px(c.view);
  so.hidden_mask = cv::Mat(3, 3, CV_8U, cv::Scalar(255));
  EXPECT_THROW(geometry::segment_device(frame.image, so), std::invalid_argument) << "a mask of another size";
}
