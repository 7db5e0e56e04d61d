// The live node on a C-arm with zoom modes (issue 31): the C-arm link says the mode of every
// state, and a frame is the image of its mode. On a simulated session whose last run switches
// from the whole detector to its central two thirds (and whose frames are the monitor's
// picture of it), the roadmap is drawn magnified 1.5 times about the picture's centre after
// the switch, the status line names the mode, and a mode node.json does not list leaves its
// frames without a roadmap and says why. The choice of a frame's field, and the options'
// refusals, without a replay.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <map>
#include <mutex>

#include "evar/node/live_node.hpp"
#include "evar/session/session_replay.hpp"
#include "evar/sim/session_generator.hpp"
#include "support/simulated_session.hpp"
#include "support/video_out.hpp"
#include "frame_field.hpp"
#include "support/node_screen.hpp"

namespace {

using namespace evar;
namespace fs = std::filesystem;

// 384 px of 0.8 mm in mode 1, shown 1.25 times enlarged and turned in a 640 x 512 frame.
geometry::VideoMapping monitor() { return test::square_image_monitor(90, false); }

class ZoomReplay : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sim::SessionPlan plan;
    plan.seed = 1;
    plan.detector_px = 384;
    plan.pixel_spacing_mm = 0.8;
    plan.fluoro_seconds = 1.0;
    plan.video_out = monitor();
    plan.zoom_change = true;
    sim_ = new test::SimulatedSession(plan);
  }
  static void TearDownTestSuite() { delete sim_; }
  static node::NodeOptions options() {
    node::NodeOptions o;
    o.detector = sim_->session().detector;
    o.zoom_modes = sim_->session().zoom_modes;
    o.registration = sim_->session().ct_to_carm;
    o.video_mapping = sim_->session().video_mapping;
    o.backpressure = true;
    o.frames_on_carm_clock = true;
    o.compositor.layer_in_background = false;
    return o;
  }
  // The session's frames taken in zoom mode 2 (the C-arm sample in force says so).
  static std::size_t frames_in_mode_2() {
    std::size_t n = 0;
    for (const auto& f : sim_->session().frames) n += session::carm_at(sim_->session(), f.timestamp_ns)->zoom_mode == 2;
    return n;
  }
  static inline test::SimulatedSession* sim_ = nullptr;
};

// Each composed live frame: its projection onto the video frame, its view and status.
class Projections final : public node::OutputSink {
 public:
  struct Shown {
    std::optional<geometry::ProjectionMatrix> P;
    std::optional<node::FrameView> view;
    bool roadmap = false;
    overlay::StatusBlock status;
  };
  std::string name() const override { return "projections"; }
  void write(const node::ComposedFrame& f) override {
    if (f.held) return;
    std::lock_guard lock(mutex);
    shown[f.sequence] = {f.P_ct, f.detector_view, f.roadmap != overlay::RoadmapShown::None, f.status};
  }
  std::mutex mutex;
  std::map<std::uint64_t, Shown> shown;
};

TEST_F(ZoomReplay, AfterTheSwitchTheRoadmapIsMagnifiedAsTheFieldIsAndTheScreenNamesTheMode) {
  ASSERT_EQ(sim_->session().zoom_modes.size(), 2u);
  ASSERT_GT(frames_in_mode_2(), 5u);
  auto sink = std::make_unique<Projections>();
  Projections& p = *sink;
  std::vector<std::unique_ptr<node::OutputSink>> sinks;
  sinks.push_back(std::move(sink));
  node::LiveNode node(sim_->scene, options(), std::move(sinks));
  session::SessionReplay replay(sim_->session(), {0.0, 1});
  node.start(replay.frames(), replay.carm());
  ASSERT_TRUE(replay.wait(std::chrono::seconds(120)));
  node.stop();
  const node::NodeStatistics s = node.statistics();
  EXPECT_EQ(s.frames_wrong_size, 0u);
  EXPECT_EQ(s.frames_zoom_unknown, 0u);
  EXPECT_GE(s.adaptations, 1u);
  EXPECT_EQ(s.models_device_outside, 0u);

  // The last run: the same angulation and table in both modes. A point in mode 2 lies 1.5
  // times as far from the picture's centre as in mode 1 (the central two thirds of the field
  // in as many pixels), in whatever direction the display turns it.
  const Eigen::Vector2d centre(100 + 240 - 0.5, 8 + 240 - 0.5);
  const auto& session = sim_->session();
  std::optional<geometry::ProjectionMatrix> P1, P2;
  std::size_t mode_2_with_roadmap = 0, mode_2_named = 0, mode_1_named = 0;
  for (const auto& [sequence, shown] : p.shown) {
    const auto& record = session.frames.at(sequence - 1);
    const session::CArmSample& c = *session::carm_at(session, record.timestamp_ns);
    if (!shown.P || !shown.view) continue;
    const bool last_view = c.primary_deg == session.carm.back().primary_deg && c.secondary_deg == session.carm.back().secondary_deg;
    const bool named_2 = test::ScreenLog::line({0, false, false, shown.status}, "zoom 20 cm");
    const bool named_1 = test::ScreenLog::line({0, false, false, shown.status}, "zoom 31 cm");
    if (c.zoom_mode == 2) {
      mode_2_with_roadmap += shown.roadmap;
      mode_2_named += named_2;
      EXPECT_NEAR(shown.view->view.col_spacing_mm, 0.8 * 2.0 / 3.0, 1e-12) << "frame " << sequence;
      if (last_view && record.source == "fluoro") P2 = shown.P;
    } else {
      mode_1_named += named_1;
      EXPECT_NEAR(shown.view->view.col_spacing_mm, 0.8, 1e-12) << "frame " << sequence;
      if (last_view) P1 = shown.P;
    }
  }
  EXPECT_GT(mode_2_with_roadmap, 0u) << "no frame after the switch had a roadmap";
  EXPECT_GT(mode_2_named, 0u) << "the status line does not name the zoom mode";
  EXPECT_GT(mode_1_named, 0u);
  ASSERT_TRUE(P1 && P2) << "no frame with a view on either side of the switch";
  for (const auto& lm : sim_->scene.landmarks) {
    const Eigen::Vector2d a = *geometry::project(*P1, lm.position_lps), b = *geometry::project(*P2, lm.position_lps);
    EXPECT_LT(((b - centre) - 1.5 * (a - centre)).norm(), 1e-6) << lm.label << ": mode 1 " << a.transpose() << ", mode 2 " << b.transpose();
  }
}

TEST_F(ZoomReplay, AModeNodeJsonDoesNotListLeavesItsFramesWithoutARoadmapAndTheScreenSaysWhy) {
  node::NodeOptions o = options();
  o.zoom_modes.pop_back();  // only mode 1
  auto screen = std::make_unique<test::ScreenLog>();
  test::ScreenLog& shown = *screen;
  std::vector<std::unique_ptr<node::OutputSink>> sinks;
  sinks.push_back(std::move(screen));
  node::LiveNode node(sim_->scene, o, std::move(sinks));
  session::SessionReplay replay(sim_->session(), {0.0, 1});
  node.start(replay.frames(), replay.carm());
  ASSERT_TRUE(replay.wait(std::chrono::seconds(120)));
  node.stop();
  const node::NodeStatistics s = node.statistics();
  // Every frame of mode 2, and perhaps the one just before the switch (nearer its state).
  EXPECT_GE(s.frames_zoom_unknown, frames_in_mode_2());
  EXPECT_LE(s.frames_zoom_unknown, frames_in_mode_2() + 1);
  EXPECT_EQ(s.frames_wrong_size, 0u);
  std::size_t said = 0;
  for (std::size_t i = 0; i < shown.size(); ++i) {
    const auto f = shown.frame(i);
    if (!test::ScreenLog::alert(f, "zoom mode 2 from the C-arm link is not one of node.json's zoom_modes (1 \"31 cm\"); add it: no roadmap"))
      continue;
    ++said;
  }
  EXPECT_GE(said, frames_in_mode_2()) << "the screen did not say why the roadmap went";
}

geometry::ZoomMode mode(int number, const std::string& name, double spacing_mm) {
  return geometry::centred_zoom_mode(number, name, 256, 256, spacing_mm);
}

TEST(FrameField, TheLinksModeOrNodeJsonsFixedOnePicksAFramesField) {
  node::NodeOptions o;
  o.detector = {256, 256, 1.2, 1.2};
  std::string why;
  // Without zoom modes: the detector, whatever the link says.
  auto fields = node::frame_fields(o);
  ASSERT_EQ(fields.size(), 1u);
  EXPECT_EQ(node::field_of(fields, o, 3, why), &fields[0]);
  EXPECT_EQ(fields[0].label(), "");

  o.zoom_modes = {mode(1, "31 cm", 1.2), mode(4, "15 cm", 0.6)};
  fields = node::frame_fields(o);
  ASSERT_EQ(fields.size(), 2u);
  EXPECT_EQ(node::field_of(fields, o, 4, why), &fields[1]);
  EXPECT_EQ(fields[1].label(), "zoom 15 cm");
  EXPECT_EQ(node::field_of(fields, o, 2, why), nullptr);
  EXPECT_EQ(why, "zoom mode 2 from the C-arm link is not one of node.json's zoom_modes (1 \"31 cm\", 4 \"15 cm\"); add it");
  EXPECT_EQ(node::field_of(fields, o, 0, why), nullptr);
  EXPECT_NE(why.find("the C-arm link does not say the zoom mode"), std::string::npos) << why;
  EXPECT_NE(why.find("node.json \"zoom_mode\""), std::string::npos) << why;
  // node.json's fixed mode wins over the link's.
  o.zoom_mode = 4;
  EXPECT_EQ(node::field_of(fields, o, 1, why), &fields[1]);
  EXPECT_EQ(node::field_of(fields, o, 0, why), &fields[1]);
  // One mode listed: a link that says none has nothing to choose.
  o.zoom_mode = 0;
  o.zoom_modes.pop_back();
  fields = node::frame_fields(o);
  EXPECT_EQ(node::field_of(fields, o, 0, why), &fields[0]);

  // A turned mode without a display mapping: the frames are its turned image.
  o.zoom_modes = {mode(1, "31 cm", 1.2)};
  o.zoom_modes[0].rows = 192;
  o.zoom_modes[0].height_mm = 192 * 1.2;
  o.zoom_modes[0].rotation_deg = 90;
  fields = node::frame_fields(o);
  EXPECT_EQ(fields[0].frame_cols, 192);
  EXPECT_EQ(fields[0].frame_rows, 256);
  ASSERT_TRUE(fields[0].video);
  // Turned clockwise: the field's top-left corner is the frame's top-right.
  EXPECT_LT((fields[0].video->to_video({0.0, 0.0}) - Eigen::Vector2d(191.0, 0.0)).norm(), 1e-9);
}

TEST(FrameField, OptionsWithZoomModesThatCannotWorkAreRefusedByName) {
  node::NodeOptions o;
  o.detector = {256, 256, 1.2, 1.2};
  o.zoom_modes = {mode(1, "31 cm", 1.2), mode(2, "20 cm", 0.8)};
  EXPECT_NO_THROW(node::check_options(o));
  const auto refused = [](const node::NodeOptions& bad) {
    try {
      node::check_options(bad);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  node::NodeOptions fixed = o;
  fixed.zoom_mode = 3;
  EXPECT_NE(refused(fixed).find("zoom_mode: 3 is not one of zoom_modes"), std::string::npos) << refused(fixed);
  node::NodeOptions twice = o;
  twice.zoom_modes[1].number = 1;
  EXPECT_NE(refused(twice).find("zoom_modes[1].mode: 1 is given twice"), std::string::npos) << refused(twice);
  node::NodeOptions big = o;
  big.zoom_modes[1] = mode(2, "40 cm", 1.6);  // larger than the detector
  EXPECT_NE(refused(big).find("zoom_modes[1]: field_of_view_dimensions_mm: the field"), std::string::npos) << refused(big);
  // The display's rectangle is square; a mode whose image is not cannot be shown in it.
  node::NodeOptions shown = o;
  geometry::VideoMapping display;
  display.video_cols = 640;
  display.video_rows = 512;
  display.image_rect = {100, 8, 480, 480};
  shown.video_mapping = display;
  EXPECT_NO_THROW(node::check_options(shown));
  shown.zoom_modes[1].rows = 128;
  shown.zoom_modes[1].height_mm = 128 * 0.8;
  EXPECT_NE(refused(shown).find("video_mapping: in zoom mode 2 \"20 cm\""), std::string::npos) << refused(shown);
}

}  // namespace
