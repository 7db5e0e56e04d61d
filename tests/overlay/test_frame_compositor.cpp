#include "evar/overlay/frame_compositor.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <chrono>
#include <memory>
#include <thread>
#include <vector>

#include "evar/geometry/carm_projection.hpp"
#include "perspective_projection.hpp"
#include "evar/sim/tube_mesh.hpp"

namespace {

using namespace evar;

// A 40 mm wide vertical tube through the isocenter, seen AP on a 256 x 256 detector of
// 1 mm pixels (magnification 1.5: the tube's shadow is 60 px wide around column 127.5).
struct Scene {
  geometry::CArmView view;
  geometry::ProjectionMatrix P;
  std::shared_ptr<overlay::RoadmapModel> model = std::make_shared<overlay::RoadmapModel>();
  std::vector<std::uint16_t> pixels;
  overlay::GreyFrame frame;

  Scene() {
    view.source_to_detector_mm = 1200;
    view.source_to_isocenter_mm = 800;
    view.detector_cols = view.detector_rows = 256;
    view.row_spacing_mm = view.col_spacing_mm = 1.0;
    P = geometry::projection_matrix(view);
    model->initial.push_back(sim::tube_mesh({{0, 0, -100}, {0, 0, 100}}, [](double) { return 20.0; }));
    model->initial_landmarks.push_back({"renal_left", Eigen::Vector3d(20, 0, 30)});
    // A horizontal ramp from 1000 to 3000: the automatic window spans it.
    pixels.resize(256 * 256);
    for (int y = 0; y < 256; ++y)
      for (int x = 0; x < 256; ++x) pixels[static_cast<std::size_t>(y * 256 + x)] = static_cast<std::uint16_t>(1000 + 2000 * x / 255);
    frame = {256, 256, 512, 16, reinterpret_cast<const std::uint8_t*>(pixels.data())};
  }
};

overlay::Bgr at(const overlay::Image& im, int x, int y) { return im.at(x, y); }

TEST(FrameCompositor, WindowLevelsSixteenBitFramesAutomaticallyAndAsTold) {
  Scene s;
  overlay::FrameCompositor automatic;
  const auto im = automatic.compose(s.frame, nullptr, nullptr, overlay::RoadmapMode::Both, {});
  // 1st to 99th percentile of the ramp: the darkest columns black, the brightest white,
  // the middle mid-grey.
  EXPECT_EQ(at(im, 0, 100).r, 0);
  EXPECT_EQ(at(im, 255, 100).r, 255);
  EXPECT_NEAR(at(im, 128, 100).r, 128, 4);
  EXPECT_NEAR(automatic.last_window().level, 2000, 30);

  overlay::FrameCompositor fixed({1, {1000.0, 1500.0}});  // 1000 .. 2000 shown
  const auto im2 = fixed.compose(s.frame, nullptr, nullptr, overlay::RoadmapMode::Both, {});
  EXPECT_EQ(at(im2, 0, 10).g, 0);
  EXPECT_NEAR(at(im2, 64, 10).g, 128, 3);   // value 1502
  EXPECT_EQ(at(im2, 200, 10).g, 255);       // beyond the window
}

TEST(FrameCompositor, DrawsTheRoadmapWhereTheVesselProjectsAndNowhereElse) {
  Scene s;
  overlay::FrameCompositor c({2, {2000.0, 2000.0}});
  const auto plain = c.compose(s.frame, nullptr, nullptr, overlay::RoadmapMode::Undeformed, {});
  const auto im = c.compose(s.frame, &s.P, s.model, overlay::RoadmapMode::Undeformed, {});
  // Inside the shadow (columns 98 .. 157): tinted; well outside: the frame's grey.
  const overlay::Bgr inside = at(im, 110, 200), grey = at(plain, 110, 200);
  EXPECT_GT(std::abs(int{inside.b} - int{inside.r}), 10) << "no tint inside the vessel";
  EXPECT_EQ(at(im, 40, 200), at(plain, 40, 200));
  EXPECT_EQ(at(im, 220, 200), at(plain, 220, 200));
  EXPECT_NE(inside, grey);
  // The landmark lands where the projection puts it: a ring of radius 6 around it.
  const Eigen::Vector2d uv = *geometry::project(s.P, s.model->initial_landmarks[0].position_lps);
  bool ring = false;
  for (int dx = -7; dx <= 7; ++dx) {
    const auto p = at(im, static_cast<int>(std::lround(uv.x())) + dx, static_cast<int>(std::lround(uv.y())));
    ring = ring || (p.r > 200 && p.g > 180 && p.b < 120);  // yellow
  }
  EXPECT_TRUE(ring);
}

// The cached layer blended into a frame equals drawing the roadmap onto that frame
// directly (every drawing step is linear in the background), to rounding: each stacked
// step (fill, outline, ring, label) rounds to 8 bits in both renders, a few levels in all.
TEST(FrameCompositor, TheCachedLayerBlendsLikeDrawingDirectly) {
  Scene s;
  overlay::FrameCompositor c({2, {2000.0, 2000.0}});
  const auto plain = c.compose(s.frame, nullptr, nullptr, overlay::RoadmapMode::Undeformed, {});
  const auto im = c.compose(s.frame, &s.P, s.model, overlay::RoadmapMode::Undeformed, {});
  overlay::Image direct = plain;
  overlay::DrawOptions draw;
  draw.supersample = 2;
  draw.label_font_scale = std::max(0.4, 0.55 * 256 / 1024.0);
  overlay::composite(direct, overlay::PerspectiveProjection(s.P, 256, 256),
                     overlay::roadmap_overlay(*s.model, overlay::RoadmapMode::Undeformed), draw);
  int worst = 0;
  for (std::size_t i = 0; i < im.bgr.size(); ++i) worst = std::max(worst, std::abs(int{im.bgr[i]} - int{direct.bgr[i]}));
  EXPECT_LE(worst, 4);
}

TEST(FrameCompositor, RendersTheLayerOncePerProjectionAndModel) {
  Scene s;
  overlay::FrameCompositor c;
  for (int i = 0; i < 5; ++i) c.compose(s.frame, &s.P, s.model, overlay::RoadmapMode::Both, {{"line"}, {}});
  EXPECT_EQ(c.layer_renders(), 1u);
  // A still C-arm's readings jitter (here 0.005°, a hundredth of a pixel at the model):
  // the same roadmap, not drawn again.
  geometry::CArmView jitter = s.view;
  jitter.primary_angle_deg = 0.005;
  const auto Pj = geometry::projection_matrix(jitter);
  c.compose(s.frame, &Pj, s.model, overlay::RoadmapMode::Both, {});
  EXPECT_EQ(c.layer_renders(), 1u);
  geometry::CArmView moved = s.view;
  moved.primary_angle_deg = 30;
  const auto P2 = geometry::projection_matrix(moved);
  c.compose(s.frame, &P2, s.model, overlay::RoadmapMode::Both, {});
  EXPECT_EQ(c.layer_renders(), 2u);
  auto adapted = std::make_shared<overlay::RoadmapModel>(*s.model);
  c.compose(s.frame, &P2, adapted, overlay::RoadmapMode::Both, {});
  EXPECT_EQ(c.layer_renders(), 3u);
}

TEST(FrameCompositor, RefusesFramesItCannotRead) {
  Scene s;
  overlay::FrameCompositor c;
  overlay::GreyFrame bad = s.frame;
  bad.stride_bytes = 100;
  EXPECT_THROW(c.compose(bad, nullptr, nullptr, overlay::RoadmapMode::Both, {}), std::invalid_argument);
  bad = s.frame;
  bad.bits = 12;
  EXPECT_THROW(c.compose(bad, nullptr, nullptr, overlay::RoadmapMode::Both, {}), std::invalid_argument);
  bad = s.frame;
  bad.data = nullptr;
  EXPECT_THROW(c.compose(bad, nullptr, nullptr, overlay::RoadmapMode::Both, {}), std::invalid_argument);
}

TEST(FrameCompositor, ModesShowWhatTheySay) {
  Scene s;
  auto m = std::make_shared<overlay::RoadmapModel>(*s.model);
  EXPECT_EQ(overlay::roadmap_overlay(*m, overlay::RoadmapMode::Adapted).layers.size(), 1u);  // nothing adapted yet: initial
  m->adapted = m->initial;
  m->adapted_landmarks = m->initial_landmarks;
  EXPECT_EQ(overlay::roadmap_overlay(*m, overlay::RoadmapMode::Both).layers.size(), 2u);
  EXPECT_EQ(overlay::roadmap_overlay(*m, overlay::RoadmapMode::Adapted).layers.front().legend, "adapted");
  EXPECT_EQ(overlay::roadmap_overlay(*m, overlay::RoadmapMode::Undeformed).layers.front().legend, "preoperative");
  EXPECT_EQ(overlay::parse_roadmap_mode("both"), overlay::RoadmapMode::Both);
  EXPECT_FALSE(overlay::parse_roadmap_mode("all"));
}

}  // namespace

namespace {
// Composes until the compositor shows `want` (its worker drew the layer), at most 10 s.
overlay::Image compose_until(overlay::FrameCompositor& c, const Scene& s, const geometry::ProjectionMatrix& P,
                             const std::shared_ptr<overlay::RoadmapModel>& model, overlay::RoadmapShown want) {
  overlay::Image out;
  for (int i = 0; i < 1000; ++i) {
    out = c.compose(s.frame, &P, model, overlay::RoadmapMode::Both, {});
    if (c.last_roadmap() == want) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return out;
}
}  // namespace

TEST(FrameCompositor, InTheBackgroundNoFrameWaitsForItsLayerAndNoneShowsAMisplacedRoadmap) {
  Scene s;
  overlay::FrameCompositor direct;  // draws every layer before returning
  overlay::CompositorOptions o;
  o.layer_in_background = true;
  overlay::FrameCompositor c(o);
  const overlay::Image plain = direct.compose(s.frame, nullptr, s.model, overlay::RoadmapMode::Both, {});

  // A new view: the frame comes back at once without a roadmap (its layer is being drawn),
  // and says so; the tube's column is bare grey.
  const overlay::Image first = c.compose(s.frame, &s.P, s.model, overlay::RoadmapMode::Both, {});
  EXPECT_EQ(c.last_roadmap(), overlay::RoadmapShown::None);
  EXPECT_EQ(at(first, 127, 200), at(plain, 127, 200));
  // Once drawn, exactly what the direct compositor shows.
  const overlay::Image drawn = compose_until(c, s, s.P, s.model, overlay::RoadmapShown::Current);
  ASSERT_EQ(c.last_roadmap(), overlay::RoadmapShown::Current);
  EXPECT_EQ(drawn.bgr, direct.compose(s.frame, &s.P, s.model, overlay::RoadmapMode::Both, {}).bgr);

  // A new model at the same view: the previous model's layer (drawn for this view) stands
  // in until the new one is drawn.
  auto adapted = std::make_shared<overlay::RoadmapModel>(*s.model);
  adapted->initial.front().V.col(0).array() += 10.0;  // moved 10 mm (15 px) to the patient's left
  c.compose(s.frame, &s.P, adapted, overlay::RoadmapMode::Both, {});
  EXPECT_EQ(c.last_roadmap(), overlay::RoadmapShown::Previous);
  const overlay::Image moved = compose_until(c, s, s.P, adapted, overlay::RoadmapShown::Current);
  EXPECT_EQ(moved.bgr, direct.compose(s.frame, &s.P, adapted, overlay::RoadmapMode::Both, {}).bgr);

  // A new angulation: no stand-in, the old layer would be misplaced.
  geometry::CArmView turned = s.view;
  turned.primary_angle_deg = 30;
  const auto P2 = geometry::projection_matrix(turned);
  c.compose(s.frame, &P2, adapted, overlay::RoadmapMode::Both, {});
  EXPECT_EQ(c.last_roadmap(), overlay::RoadmapShown::None);
  compose_until(c, s, P2, adapted, overlay::RoadmapShown::Current);
  EXPECT_EQ(c.last_roadmap(), overlay::RoadmapShown::Current);
  EXPECT_EQ(c.layer_renders(), 3u);
}

TEST(FrameCompositor, InTheBackgroundALayerForAViewLeftBehindEvictsNothing) {
  // The C-arm settles at B, then comes back to A before B's layer is drawn: A keeps its
  // roadmap when B's layer arrives, and B's is there at once if the C-arm returns to B.
  Scene s;
  overlay::CompositorOptions o;
  o.layer_in_background = true;
  overlay::FrameCompositor c(o);
  compose_until(c, s, s.P, s.model, overlay::RoadmapShown::Current);
  geometry::CArmView b = s.view;
  b.primary_angle_deg = 30;
  const auto Pb = geometry::projection_matrix(b);
  c.compose(s.frame, &Pb, s.model, overlay::RoadmapMode::Both, {});
  EXPECT_EQ(c.last_roadmap(), overlay::RoadmapShown::None);
  for (int i = 0; i < 1000 && c.layer_renders() < 2; ++i) {
    c.compose(s.frame, &s.P, s.model, overlay::RoadmapMode::Both, {});  // back at A meanwhile
    EXPECT_EQ(c.last_roadmap(), overlay::RoadmapShown::Current);
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_EQ(c.layer_renders(), 2u);
  c.compose(s.frame, &s.P, s.model, overlay::RoadmapMode::Both, {});  // B's layer arrives here
  EXPECT_EQ(c.last_roadmap(), overlay::RoadmapShown::Current);
  c.compose(s.frame, &Pb, s.model, overlay::RoadmapMode::Both, {});
  EXPECT_EQ(c.last_roadmap(), overlay::RoadmapShown::Current);  // kept, not drawn again
  EXPECT_EQ(c.layer_renders(), 2u);
}

TEST(FrameCompositor, InTheBackgroundALayerThatCannotBeDrawnLeavesTheFramesGoingAndSaysWhy) {
  Scene s;
  overlay::CompositorOptions o;
  o.layer_in_background = true;
  overlay::FrameCompositor c(o);
  overlay::FrameCompositor direct;
  const overlay::Image plain = direct.compose(s.frame, nullptr, s.model, overlay::RoadmapMode::Both, {});
  // A landmark that is not finite: the drawing refuses the model on the worker thread.
  auto broken = std::make_shared<overlay::RoadmapModel>(*s.model);
  broken->initial_landmarks.front().position_lps.x() = std::numeric_limits<double>::quiet_NaN();
  overlay::Image out;
  for (int i = 0; i < 1000 && c.last_layer_error().empty(); ++i) {
    out = c.compose(s.frame, &s.P, broken, overlay::RoadmapMode::Both, {});
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_THAT(c.last_layer_error(), testing::HasSubstr("not finite"));
  EXPECT_EQ(c.last_roadmap(), overlay::RoadmapShown::None);
  EXPECT_EQ(at(out, 127, 200), at(plain, 127, 200));  // the frame itself, no roadmap
  EXPECT_EQ(c.layer_renders(), 0u);
  // A good model again: its roadmap comes and the error is gone.
  compose_until(c, s, s.P, s.model, overlay::RoadmapShown::Current);
  EXPECT_EQ(c.last_roadmap(), overlay::RoadmapShown::Current);
  EXPECT_TRUE(c.last_layer_error().empty());
}
