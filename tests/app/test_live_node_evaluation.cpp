// The live node end to end on a replayed simulated session, measured against the
// session's truth by eval's sink: the adapted overlay appears and the ostia's projected
// error falls.
#include <gtest/gtest.h>

#include <filesystem>

#include "evar/node/live_node.hpp"
#include "evar/node/output_sinks.hpp"
#include "evar/session/session_replay.hpp"
#include "session_evaluation.hpp"
#include "support/live_node_replay.hpp"

namespace {

using namespace evar;
namespace fs = std::filesystem;
using test::LiveNodeReplay;

TEST_F(LiveNodeReplay, TheAdaptedOverlayAppearsAndTheOstiumErrorFalls) {
  node::NodeOptions o = options();
  o.backpressure = true;  // a replay can wait: every frame is shown
  std::vector<std::unique_ptr<node::OutputSink>> sinks;
  auto video = std::make_unique<node::VideoSink>(dir_ / "out" / "overlay.avi", 15.0);
  auto snapshots = std::make_unique<node::SnapshotSink>(dir_ / "out" / "snapshots");
  auto* video_ptr = video.get();
  auto* snapshots_ptr = snapshots.get();
  auto evaluation = std::make_unique<app::EvaluationSink>(session(), *scene_);
  auto* evaluation_ptr = evaluation.get();
  sinks.push_back(std::move(evaluation));
  sinks.push_back(std::move(video));
  sinks.push_back(std::move(snapshots));
  node::LiveNode node(*scene_, o, std::move(sinks));
  // Twice through: the frames after the first model then do not depend on how fast the
  // deformation is (about 2 s under AddressSanitizer, the length of one pass).
  constexpr int kLoops = 2;
  ASSERT_TRUE(replay_through(node, kLoops));
  const node::NodeStatistics s = node.statistics();
  EXPECT_EQ(s.frames_composited, kLoops * session().frames.size());
  EXPECT_EQ(s.dropped_input + s.dropped_output, 0u);
  ASSERT_GE(s.adaptations, 1u) << s.last_failure;
  ASSERT_TRUE(node.model()->adapted);
  // Every view pair, and every pair on screen adapted again after the pelvis moved the
  // models, is accounted for: adapted, failed, or superseded (by a newer pair, or left when
  // the node stopped).
  EXPECT_EQ(s.pairs + s.readaptations, s.adaptations + s.adaptation_failures + s.pairs_superseded);
  EXPECT_EQ(video_ptr->frames(), kLoops * session().frames.size());
  EXPECT_GT(fs::file_size(dir_ / "out" / "overlay.avi"), 10000u);
  // Before and after the first model, as pictures.
  EXPECT_TRUE(fs::exists(dir_ / "out" / "snapshots" / "model-1-before.png"));
  EXPECT_TRUE(fs::exists(dir_ / "out" / "snapshots" / "model-1-after.png"));
  EXPECT_GE(snapshots_ptr->kept().size(), 2u);
  // The frames shown with the adapted model: the internal iliac ostium of the iliac that
  // carries the wire, which the method moves, projects closer to the true ostium than from
  // the preoperative model (by more than half a pixel: 0.25 mm); no landmark ends up
  // farther by more than 1 mm (about 2 px).
  // Which view pairs are adapted depends on timing, so nothing here depends on which.
  const auto errors = evaluation_ptr->result();
  ASSERT_GT(evaluation_ptr->frames(), 20u);
  const std::string carrier_ostium = "internal_" + generated_->carrier;  // internal_iliac_right
  bool seen = false;
  for (const auto& l : errors) {
    if (l.label == carrier_ostium) {
      seen = true;
      EXPECT_LT(l.adapted_mm, l.initial_mm - 0.25) << l.label << ": initial " << l.initial_mm << " mm, adapted " << l.adapted_mm;
    }
    EXPECT_LT(l.adapted_mm, l.initial_mm + 1.0) << l.label << ": initial " << l.initial_mm << " mm, adapted " << l.adapted_mm;
  }
  EXPECT_TRUE(seen) << "no landmark " << carrier_ostium;
  EXPECT_GT(s.latency_ms.n, 0u);
  // A stopped node does not run again (its queues are closed): said, not silently idle.
  session::SessionReplay again(session(), {0.0, 1});
  EXPECT_THROW(node.start(again.frames(), again.carm()), std::logic_error);
}

}  // namespace
