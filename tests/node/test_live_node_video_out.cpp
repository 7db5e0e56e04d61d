// The live node on a C-arm's video output (issue 31): frames are the monitor's picture, the
// detector image scaled into a rectangle, turned and mirrored, text burned in around it.
// With the video mapping the node finds the device on the detector's pixels, adapts the
// model, and draws the roadmap where the monitor shows the detector; without it a frame of
// the video's size is said to be the wrong size and gets no roadmap.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <mutex>
#include <string>
#include <utility>
#include <vector>
#include <opencv2/imgproc.hpp>

#include "evar/geometry/video_frame.hpp"
#include "evar/node/live_node.hpp"
#include "evar/session/session_replay.hpp"
#include "evar/sim/session_generator.hpp"
#include "support/simulated_session.hpp"
#include "support/video_out.hpp"

namespace {

using namespace evar;
namespace fs = std::filesystem;

// 384 px detector of 0.8 mm shown 1.25 times enlarged, turned 270° and mirrored, in a
// 640 x 512 frame with text left and right of the picture.
geometry::VideoMapping monitor() { return test::square_image_monitor(270, true); }

class VideoOutReplay : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sim::SessionPlan plan;
    plan.seed = 1;
    plan.detector_px = 384;
    plan.pixel_spacing_mm = 0.8;
    plan.fluoro_seconds = 1.0;
    plan.video_out = monitor();
    sim_ = new test::SimulatedSession(plan);
  }
  static void TearDownTestSuite() { delete sim_; }
  // With the session's video mapping, or (`mapped` false) as if the frames were the detector's.
  static node::NodeOptions options(bool mapped = true) {
    node::NodeOptions o;
    o.detector = sim_->session().detector;
    o.registration = sim_->session().ct_to_carm;
    if (mapped) o.video_mapping = sim_->session().video_mapping;
    o.backpressure = true;
    o.frames_on_carm_clock = true;  // a replay: frames and C-arm samples on the session's clock
    o.compositor.layer_in_background = false;  // every frame with its roadmap drawn
    o.mode = overlay::RoadmapMode::Undeformed;
    return o;
  }
  static inline test::SimulatedSession* sim_ = nullptr;
};

// Each composed frame with a view: its size, its projection and where its roadmap is drawn.
class FrameChecker final : public node::OutputSink {
 public:
  explicit FrameChecker(const geometry::VideoToDetector& map, const geometry::Scene& scene) : map_(map), scene_(scene) {}
  std::string name() const override { return "frame checker"; }
  void write(const node::ComposedFrame& f) override {
    std::lock_guard lock(mutex_);
    ++frames;
    if (f.image->width != map_.video_cols() || f.image->height != map_.video_rows()) ++wrong_size;
    if (!f.P_ct || !f.detector_view || f.held) return;
    ++with_view;
    const geometry::ProjectionMatrix expected = geometry::projection_on_video(f.detector_view->P_ct, map_);
    worst_projection_difference = std::max(worst_projection_difference, (*f.P_ct - expected).cwiseAbs().maxCoeff() /
                                                                            expected.cwiseAbs().maxCoeff());
    scale_ratio = f.mm_per_px * map_.video_px_per_detector_px() / node::mm_at_isocenter_per_px(f.detector_view->view);
    if (f.roadmap == overlay::RoadmapShown::None) return;
    // Where the vessels project on the video frame, below the status block (top left).
    Eigen::AlignedBox2d vessels;
    for (const auto& v : scene_.vessels)
      for (Eigen::Index i = 0; i < v.mesh.mesh.V.rows(); ++i)
        if (const auto px = geometry::project(*f.P_ct, v.mesh.mesh.V.row(i).transpose())) vessels.extend(*px);
    const int first_row = map_.video_rows() / 2;  // the status block ends well above
    std::size_t inside = 0, outside = 0;
    for (int y = first_row; y < f.image->height; ++y)
      for (int x = 0; x < f.image->width; ++x) {
        const auto c = f.image->at(x, y);
        const int chroma = std::abs(int{c.b} - int{c.g}) + std::abs(int{c.g} - int{c.r});
        if (chroma < 40) continue;  // grey: the fluoroscopy, the border, the burned-in text
        const bool near = x >= vessels.min().x() - 4 && x <= vessels.max().x() + 4 && y >= vessels.min().y() - 4 &&
                          y <= vessels.max().y() + 4;
        ++(near ? inside : outside);
      }
    roadmap_pixels_inside += inside;
    roadmap_pixels_outside += outside;
  }
  std::mutex mutex_;
  std::size_t frames = 0, wrong_size = 0, with_view = 0, roadmap_pixels_inside = 0, roadmap_pixels_outside = 0;
  double worst_projection_difference = 0.0, scale_ratio = 0.0;

 private:
  const geometry::VideoToDetector& map_;
  const geometry::Scene& scene_;
};

TEST_F(VideoOutReplay, TheNodeAdaptsTheModelAndDrawsTheRoadmapWhereTheMonitorShowsTheDetector) {
  const geometry::VideoToDetector map(monitor(), sim_->session().detector.cols, sim_->session().detector.rows);
  auto checker = std::make_unique<FrameChecker>(map, sim_->scene);
  FrameChecker& shown = *checker;
  std::vector<std::unique_ptr<node::OutputSink>> sinks;
  sinks.push_back(std::move(checker));
  node::LiveNode node(sim_->scene, options(), std::move(sinks));
  session::SessionReplay replay(sim_->session(), {0.0, 1});
  node.start(replay.frames(), replay.carm());
  ASSERT_TRUE(replay.wait(std::chrono::seconds(120)));
  node.stop();
  const node::NodeStatistics s = node.statistics();
  EXPECT_EQ(s.frames_composited, sim_->session().frames.size());
  EXPECT_EQ(s.frames_wrong_size, 0u);
  EXPECT_GE(s.adaptations, 1u) << "the device was not found on the detector image read out of the video frames";
  EXPECT_EQ(s.models_device_outside, 0u);
  EXPECT_GT(s.frames_with_roadmap, 0u);
  EXPECT_EQ(shown.wrong_size, 0u) << "frames keep their video size on screen";
  EXPECT_GT(shown.with_view, 0u);
  EXPECT_LT(shown.worst_projection_difference, 1e-12);
  EXPECT_NEAR(shown.scale_ratio, 1.0, 1e-12);
  // The roadmap lies where the vessels project through the mapping (a turn or mirror missed
  // would put most of it elsewhere in the picture).
  EXPECT_GT(shown.roadmap_pixels_inside, 1000u);
  EXPECT_LT(shown.roadmap_pixels_outside, shown.roadmap_pixels_inside / 100);
}

// A frame source whose frames `from` to `to` show a menu over the image area instead of
// fluoroscopy: a flat grey panel with dark lines of text, as a C-arm's setup screen.
class MenuFrames final : public acquisition::FrameSource {
 public:
  MenuFrames(acquisition::FrameSource& inner, std::uint64_t from, std::uint64_t to) : inner_(inner), from_(from), to_(to) {}
  void start(FrameCallback on_frame, StateCallback on_state) override {
    inner_.start(
        [this, on_frame](const acquisition::Frame& f) {
          if (f.sequence < from_ || f.sequence >= to_) return on_frame(f);
          acquisition::Frame menu = f;
          cv::Mat picture(f.height, f.width, CV_16UC1, menu.pixels.data(), static_cast<std::size_t>(f.stride_bytes));
          picture.setTo(cv::Scalar(21000));
          for (int line = 0; line < 12; ++line)
            cv::putText(picture, "SETUP  PROTOCOL " + std::to_string(line) + "  ABDOMEN  15 P/S", {120, 60 + 36 * line},
                        cv::FONT_HERSHEY_SIMPLEX, 0.8, cv::Scalar(2000), 2);
          on_frame(menu);
        },
        std::move(on_state));
  }
  void stop() override { inner_.stop(); }
  acquisition::StreamState state() const override { return inner_.state(); }
  acquisition::SequenceStats statistics() const override { return inner_.statistics(); }
  std::string description() const override { return "a menu shown for a while"; }

 private:
  acquisition::FrameSource& inner_;
  std::uint64_t from_, to_;
};

// The alerts on screen that begin with `prefix`: the frames that showed them, and what they said.
class AlertRecorder final : public node::OutputSink {
 public:
  explicit AlertRecorder(std::string prefix) : prefix_(std::move(prefix)) {}
  std::string name() const override { return "alert recorder"; }
  void write(const node::ComposedFrame& f) override {
    for (const auto& a : f.status.alerts)
      if (a.rfind(prefix_, 0) == 0) {
        frames.push_back(f.sequence);
        said.push_back(a);
      }
  }
  std::vector<std::uint64_t> frames;
  std::vector<std::string> said;

 private:
  std::string prefix_;
};

// The live fluoroscopy is never taken for anything else; a menu over the image area is not
// searched for a device, and the screen says so while it lasts.
TEST_F(VideoOutReplay, AMenuOverTheImageIsNotSearchedForADeviceAndIsSaidOnScreen) {
  for (const bool menu : {false, true}) {
    SCOPED_TRACE(menu ? "frames 5-14 a menu" : "all fluoroscopy");
    auto recorder = std::make_unique<AlertRecorder>("video: not fluoroscopy");
    AlertRecorder& shown = *recorder;
    std::vector<std::unique_ptr<node::OutputSink>> sinks;
    sinks.push_back(std::move(recorder));
    node::LiveNode node(sim_->scene, options(), std::move(sinks));
    session::SessionReplay replay(sim_->session(), {0.0, 1});
    MenuFrames frames(replay.frames(), menu ? 5 : 0, menu ? 15 : 0);
    node.start(frames, replay.carm());
    ASSERT_TRUE(replay.wait(std::chrono::seconds(120)));
    node.stop();
    const node::NodeStatistics s = node.statistics();
    if (!menu) {
      EXPECT_EQ(s.frames_not_fluoroscopy, 0u) << "fluoroscopy (and DSA) taken for something else";
      EXPECT_TRUE(shown.said.empty());
      continue;
    }
    // The first view's fluoroscopy is frames 1-15: the menu frames among those analysed.
    EXPECT_GE(s.frames_not_fluoroscopy, 1u);
    ASSERT_FALSE(shown.said.empty());
    EXPECT_GE(shown.frames.front(), 5u);
    EXPECT_GE(s.adaptations, 1u) << "the fluoroscopy around the menu still adapts the model";
  }
}

TEST_F(VideoOutReplay, WithoutTheMappingAVideoFrameIsTheWrongSizeAndGetsNoRoadmap) {
  node::LiveNode node(sim_->scene, options(false), {});
  session::SessionReplay replay(sim_->session(), {0.0, 1});
  node.start(replay.frames(), replay.carm());
  ASSERT_TRUE(replay.wait(std::chrono::seconds(120)));
  node.stop();
  const node::NodeStatistics s = node.statistics();
  EXPECT_EQ(s.frames_wrong_size, sim_->session().frames.size());
  EXPECT_EQ(s.frames_with_roadmap, 0u);
  EXPECT_EQ(s.adaptations, 0u);
}

TEST(VideoOutOptions, AMappingThatDoesNotFitTheDetectorIsRefusedByName) {
  node::NodeOptions o;
  o.detector = {384, 384, 0.8, 0.8};
  o.video_mapping = monitor();
  o.video_mapping->image_rect = {100, 8, 480, 400};  // not square: the detector is
  try {
    node::check_options(o);
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("node options: video_mapping: video mapping: image_rect_px [100, 8, 480, 400]"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace

// The picture no longer where the mapping says (the monitor's layout changed, or the mapping
// was made for another): said on screen while it lasts, the log and the counts say what does
// not fit; with the right mapping nothing is said.
TEST_F(VideoOutReplay, AMappingThatNoLongerFitsThePictureIsSaidOnScreen) {
  for (const bool wrong : {false, true}) {
    SCOPED_TRACE(wrong ? "the mapping 10 px below the picture" : "the session's mapping");
    node::NodeOptions o = options();
    o.video_mapping_check = std::chrono::milliseconds(1);  // every analysed frame
    if (wrong) o.video_mapping->image_rect.y += 10.0;
    auto recorder = std::make_unique<AlertRecorder>("VIDEO MAPPING DOES NOT FIT");
    AlertRecorder& shown = *recorder;
    std::vector<std::unique_ptr<node::OutputSink>> sinks;
    sinks.push_back(std::move(recorder));
    node::LiveNode node(sim_->scene, o, std::move(sinks));
    session::SessionReplay replay(sim_->session(), {0.0, 1});
    node.start(replay.frames(), replay.carm());
    ASSERT_TRUE(replay.wait(std::chrono::seconds(120)));
    node.stop();
    const node::NodeStatistics s = node.statistics();
    EXPECT_GE(s.video_mapping_checks, 3u);
    if (!wrong) {
      EXPECT_EQ(s.video_mapping_misfits, 0u) << s.last_video_mapping_misfit;
      EXPECT_TRUE(shown.said.empty()) << shown.said.front();
      continue;
    }
    EXPECT_EQ(s.video_mapping_misfits, s.video_mapping_checks);
    EXPECT_NE(s.last_video_mapping_misfit.find("10 px above the mapping's image rectangle"), std::string::npos)
        << s.last_video_mapping_misfit;
    ASSERT_FALSE(shown.said.empty());
    EXPECT_NE(shown.said.front().find("the roadmap may be misplaced"), std::string::npos) << shown.said.front();
  }
}

// The display mirrors the picture and the mapping says it does not: the device still
// reconstructs from the mirrored views (their epipolar geometry holds), but the oblique
// views' bones match only mirrored. Said on screen, with what the mapping needs; with the
// right mapping nothing is said. Without the bones the device says it, naming the turns
// it reads right under and no fix.
TEST_F(VideoOutReplay, AMappingThatMissesTheMirrorIsSaidOnScreen) {
  for (const int run : {0, 1, 2}) {
    const bool wrong = run > 0, bones = run < 2;
    SCOPED_TRACE(!wrong ? "the session's mapping" : bones ? "the mapping without its mirror" : "the same, no bones");
    node::NodeOptions o = options();
    if (wrong) o.video_mapping->mirror = false;
    o.pelvis.enabled = bones;
    auto recorder = std::make_unique<AlertRecorder>("PICTURE");
    AlertRecorder& shown = *recorder;
    std::vector<std::unique_ptr<node::OutputSink>> sinks;
    sinks.push_back(std::move(recorder));
    node::LiveNode node(sim_->scene, o, std::move(sinks));
    // The bones are checked beside the frames, a view's after its first frame: played twice
    // at twice the pace, the second time through shows what the first found, however slowly
    // the checks run (the sanitizers).
    session::SessionReplay replay(sim_->session(), {2.0, wrong ? 2 : 1});
    node.start(replay.frames(), replay.carm());
    ASSERT_TRUE(replay.wait(std::chrono::seconds(120)));
    node.stop();
    const node::NodeStatistics s = node.statistics();
    EXPECT_GE(s.orientation_checks, bones ? 3u : 1u) << "the three views' bones, or the pairs' device";
    if (!wrong) {
      EXPECT_EQ(s.orientation_alerts, 0u) << s.last_orientation_alert;
      EXPECT_TRUE(shown.said.empty()) << shown.said.front();
      continue;
    }
    EXPECT_GE(s.orientation_alerts, 1u) << s.last_orientation_misfit;
    if (!bones) {
      ASSERT_FALSE(shown.said.empty()) << s.last_orientation_alert;
      for (const auto& a : shown.said) {
        EXPECT_EQ(a.rfind("PICTURE TURNED OR MIRRORED? the device lies in the vessels only if", 0), 0u) << a;
        EXPECT_NE(a.find("check the display's turn and mirror"), std::string::npos) << a;
        EXPECT_EQ(a.find("would need"), std::string::npos) << a;
      }
      continue;
    }
    // The display turns the picture 270° and then mirrors it; the mapping said no mirror.
    // On screen the roadmap is drawn left for right. Whatever names a fix names that one (the
    // bones single it out; the device may read as well otherwise and then names both turns,
    // and no fix).
    const std::string fix = "\"mirror\": true, \"rotation_deg\": 270 (it has false, 270)";
    std::size_t with_fix = 0;
    for (const auto& a : shown.said) {
      if (a.find("would need") == std::string::npos) continue;
      ++with_fix;
      EXPECT_NE(a.find(fix), std::string::npos) << a;
      EXPECT_EQ(a.rfind("PICTURE MIRRORED?", 0), 0u) << a;
      EXPECT_NE(a.find("roadmap drawn left for right"), std::string::npos) << a;
    }
    EXPECT_GT(with_fix, 0u) << s.last_orientation_alert;
    EXPECT_FALSE(shown.said.empty()) << "said in the log, not on screen";
  }
}
