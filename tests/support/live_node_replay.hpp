#pragma once
// A simulated session (seed 1, 512 px) generated once per test suite, and a live node run
// through its replay: the fixture the node's end-to-end tests share (tests/node and the
// evaluation's in tests/app).
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <string>

#include "evar/geometry/scene.hpp"
#include "evar/node/live_node.hpp"
#include "evar/session/session_replay.hpp"
#include "evar/sim/session_generator.hpp"

namespace evar::test {

class LiveNodeReplay : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::filesystem::temp_directory_path() / ("evar-live-node-" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir_);
    sim::SessionPlan plan;
    plan.seed = 1;
    plan.detector_px = 512;
    plan.pixel_spacing_mm = 0.6;
    generated_ = new sim::GeneratedSession(sim::generate_session(plan, dir_ / "session"));
    scene_ = new geometry::Scene(geometry::load_scene(dir_ / "session" / generated_->session.scene));
  }
  static void TearDownTestSuite() {
    delete scene_;
    delete generated_;
    std::filesystem::remove_all(dir_);
  }
  static node::NodeOptions options() {
    node::NodeOptions o;
    o.detector = generated_->session.detector;
    o.registration = generated_->session.ct_to_carm;
    return o;
  }
  // A node that notices a stall after 300 ms and holds a frame every 200 ms.
  static node::NodeOptions stall_options() {
    node::NodeOptions o = options();
    o.video_stall = std::chrono::milliseconds(300);
    o.held_frame_interval = std::chrono::milliseconds(200);
    return o;
  }
  static const session::Session& session() { return generated_->session; }
  // The whole session through the node as fast as it takes it, `loops` times; false if the
  // replay hangs.
  static bool replay_through(node::LiveNode& node, int loops = 1) {
    session::SessionReplay replay(session(), {0.0, loops});
    node.start(replay.frames(), replay.carm());
    const bool done = replay.wait(std::chrono::seconds(120));
    node.stop();
    return done;
  }

  static inline std::filesystem::path dir_;
  static inline sim::GeneratedSession* generated_ = nullptr;
  static inline geometry::Scene* scene_ = nullptr;
};

}  // namespace evar::test
