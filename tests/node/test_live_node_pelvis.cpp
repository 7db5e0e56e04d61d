// The live node finds the pelvis in the bones of the frames it analyses and bends the models
// moved with it (node/pelvis_tracker.hpp), on a simulated session at the paper's difficulty
// (the pelvis off on the table, the registration off by a residual): the screen says where
// it was found, the model on screen is made again from the moved models, and the pose found
// puts the internal iliac ostia near where the pelvis truly carried them.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <functional>
#include <thread>

#include <nlohmann/json.hpp>

#include "evar/geometry/markups.hpp"
#include "evar/node/live_node.hpp"
#include "evar/session/session_replay.hpp"
#include "evar/sim/session_generator.hpp"
#include "support/node_screen.hpp"
#include "support/temp_dir.hpp"

namespace {

using namespace evar;

class LiveNodePelvis : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    sim::SessionPlan plan;
    plan.seed = 3;
    plan.difficulty = sim::Difficulty::Paper;
    plan.physics = sim::TruthPhysics::Conforming;
    plan.detector_px = 256;
    plan.pixel_spacing_mm = 1.2;
    plan.fluoro_seconds = 1.0;
    generated_ = new sim::GeneratedSession(sim::generate_session(plan, dir_->path / "session"));
    scene_ = new geometry::Scene(geometry::load_scene(dir_->path / "session" / generated_->session.scene));
  }
  static void TearDownTestSuite() {
    delete scene_;
    delete generated_;
    delete dir_;
  }
  static node::NodeOptions options() {
    node::NodeOptions o;
    o.detector = generated_->session.detector;
    o.registration = generated_->session.ct_to_carm;
    o.frames_on_carm_clock = true;
    o.backpressure = true;
    return o;
  }
  // The session (13 s) at `pace` times its own: at four, each view still stays long enough
  // for a frame of it to be analysed after the adaptation before it (as fast as the node
  // takes them, a short view's frames may all go by while the analysis waits).
  // `until`: what to wait for (at most a minute: slower under the sanitizers) once the
  // frames are through, before the node stops; a model on its way is not left behind.
  static void replay_through(node::LiveNode& node, double pace, const std::function<bool()>& until = [] { return true; }) {
    session::SessionReplay replay(generated_->session, {pace, 1});
    node.start(replay.frames(), replay.carm());
    ASSERT_TRUE(replay.wait(std::chrono::seconds(120))) << "the replay hung";
    for (int i = 0; i < 600 && !until(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    node.stop();
  }

  static inline test::TempDir* dir_ = nullptr;
  static inline sim::GeneratedSession* generated_ = nullptr;
  static inline geometry::Scene* scene_ = nullptr;
};

TEST_F(LiveNodePelvis, ThePelvisFoundInTheBonesMovesTheModelsTheNodeBendsAndTheScreenSaysSo) {
  ASSERT_GT(scene_->pelvis.V.rows(), 0) << "the simulated patient's scene has no pelvis";
  test::LogCapture log;
  auto screen = std::make_unique<test::ScreenLog>();
  test::ScreenLog* shown = screen.get();
  std::vector<std::unique_ptr<node::OutputSink>> sinks;
  sinks.push_back(std::move(screen));
  node::LiveNode node(*scene_, options(), std::move(sinks));
  // In the session's own time: the screen must show frames after the models moved, and
  // under the sanitizers preparing, registering and bending take seconds (at four times the
  // pace the video had ended before the moved model came).
  replay_through(node, 1.0, [&] { return node.model()->pelvis != nullptr; });
  const node::NodeStatistics s = node.statistics();
  const std::string text = log.text();
  EXPECT_GE(s.pelvis_views, 2u) << text;
  EXPECT_GE(s.pelvis_registrations, 1u);
  ASSERT_GE(s.pelvis_found, 1u) << s.last_pelvis << "\n" << text;
  ASSERT_GE(s.pelvis_moves, 1u) << text;
  ASSERT_TRUE(s.pelvis_shift_mm.has_value());
  EXPECT_NE(text.find("pelvis found in"), std::string::npos) << text;
  // A model was on screen before the models moved, or one came after: either way the model
  // shown last was bent from the moved ones.
  const auto model = node.model();
  ASSERT_TRUE(model->adapted) << text;
  ASSERT_NE(model->pelvis, nullptr) << "the last model was bent from the models as registered\n" << text;
  EXPECT_TRUE(model->pelvis->found);
  EXPECT_EQ(s.pairs + s.readaptations, s.adaptations + s.adaptation_failures + s.pairs_superseded);
  // The model on screen is the newest pair's: a pair adapted again never comes back over a
  // newer one. Only the pairs the views formed count towards the second view's wait.
  std::uint64_t newest_later = 0;
  for (auto at = text.find("view pair: frames "); at != std::string::npos; at = text.find("view pair: frames ", at + 1)) {
    const auto and_at = text.find(" and ", at);
    newest_later = std::max<std::uint64_t>(newest_later, std::stoull(text.substr(and_at + 5)));
  }
  EXPECT_EQ(model->adapted->frame_later, newest_later) << text;
  EXPECT_EQ(s.adaptation_ms.n, s.adaptations - s.readaptations) << text;
  // The screen's pelvis line: from the first frame on, and what it says after the move.
  ASSERT_GT(shown->size(), 0u);
  EXPECT_TRUE(test::ScreenLog::line(shown->frame(0), "pelvis: looking for it in the bones")) << "the first frame";
  EXPECT_NE(s.pelvis_status.find("from the registration; models moved with it"), std::string::npos) << s.pelvis_status;
  const std::size_t said = shown->wait_for(0, [](const test::ScreenLog::Shown& f) {
    return test::ScreenLog::line(f, "pelvis: ") && test::ScreenLog::line(f, "models moved with it");
  }, std::chrono::seconds(1));
  EXPECT_LT(said, shown->size()) << "no frame said the models were moved with the pelvis";

  // Where the pose puts the internal iliac ostia's pelvis against where the pelvis truly
  // carried them: through the true registration, the one given to the node, and the
  // posture's shift of the pelvis.
  const session::Session& session = generated_->session;
  ASSERT_TRUE(session.truth && session.truth->ct_to_carm);
  const Eigen::Matrix4d M = session.ct_to_carm.inverse() * *session.truth->ct_to_carm;
  const auto patient = nlohmann::json::parse(std::ifstream(dir_->path / "session" / "patient" / "patient.json"));
  const auto& shift_json = patient["posture_change"]["pelvis_shift_mm"];
  const Eigen::Vector3d shift(shift_json[0].get<double>(), shift_json[1].get<double>(), shift_json[2].get<double>());
  const geometry::PelvisRegistration& pose = *model->pelvis;
  int ostia = 0;
  for (const auto& lm : scene_->landmarks) {
    if (lm.label.rfind("internal_iliac", 0) != 0) continue;
    ++ostia;
    const Eigen::Vector3d x = lm.position_lps;
    const Eigen::Vector3d truth = (M * (x + shift).homogeneous()).head<3>();
    const Eigen::Vector3d found = pose.rotation * (x - pose.pivot_mm) + pose.pivot_mm + pose.shift_mm;
    // On 256-pixel frames (0.8 mm at the isocenter): within 5 pixels, and within a quarter of
    // how far the pelvis truly lies from where it was registered.
    EXPECT_LT((found - truth).norm(), 4.0) << lm.label;
    EXPECT_LT((found - truth).norm(), 0.25 * (truth - x).norm()) << lm.label << ": truth moved " << (truth - x).norm() << " mm";
  }
  EXPECT_EQ(ostia, 2);
}

TEST_F(LiveNodePelvis, SwitchedOffTheModelsStayWhereTheRegistrationPutThem) {
  node::NodeOptions o = options();
  o.pelvis.enabled = false;
  auto screen = std::make_unique<test::ScreenLog>();
  test::ScreenLog* shown = screen.get();
  std::vector<std::unique_ptr<node::OutputSink>> sinks;
  sinks.push_back(std::move(screen));
  node::LiveNode node(*scene_, o, std::move(sinks));
  replay_through(node, 4.0);
  const node::NodeStatistics s = node.statistics();
  EXPECT_EQ(s.pelvis_views, 0u);
  EXPECT_EQ(s.pelvis_registrations, 0u);
  EXPECT_TRUE(s.pelvis_status.empty());
  ASSERT_TRUE(node.model()->adapted);
  EXPECT_EQ(node.model()->pelvis, nullptr);
  for (std::size_t i = 0; i < shown->size(); ++i) ASSERT_FALSE(test::ScreenLog::line(shown->frame(i), "pelvis:")) << "frame " << i;
}

}  // namespace
