// `evarnode record` end to end over the real transports: a session is played as a GigE
// Vision camera on 127.0.0.1 and a C-arm link on a pseudo-terminal; the command records
// it through the real Aravis and termios sources, and the recording is read back.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <thread>

#include "evar/acquisition/gige_camera_source.hpp"
#include "evar/app/cli.hpp"
#include "evar/session/session_replay.hpp"
#include "evar/sim/example_scene.hpp"
#include "evar/sim/gige_frame_server.hpp"
#include "evar/sim/serial_carm_server.hpp"
#include "support/ramp_frames.hpp"

namespace sim = evar::sim;
namespace session = evar::session;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

namespace {

bool same_pixels(const cv::Mat& a, const cv::Mat& b) { return a.size() == b.size() && cv::norm(a, b, cv::NORM_INF) == 0.0; }

}  // namespace

TEST(RecordCommand, RecordsAGigECameraAndASerialCArmLinkIntoASessionThatReadsBack) {
  const fs::path dir = fs::path(testing::TempDir()) / ("evar_record_cmd_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  sim::ExampleSceneParams p;
  p.aorta_vertices = 800;
  p.iliac_vertices = 400;
  sim::write_example_scene(sim::make_example_scene(p), dir / "plan");
  std::ofstream(dir / "plan" / "registration.json") << R"({"matrix": [[1,0,0,-5],[0,1,0,0],[0,0,1,0],[0,0,0,1]]})";

  // The original: frames every 200 ms; the C-arm changes halfway between frames, so which
  // state is in force at a frame is clear by 100 ms either way.
  session::Session s;
  s.scene = "scene.json";
  s.detector = {128, 96, 0.3, 0.3};  // Aravis 0.8.26's fake camera loses packets of frames under ~6 KB
  const std::vector<cv::Mat> images = evar::test::add_ramp_frames(s, 8, 200'000'000LL, {6000, 67, 5, 1});
  for (int j = -1; j < 7; ++j) {
    session::CArmSample c;
    c.timestamp_ns = 1'100'000'000LL + j * 200'000'000LL;
    c.primary_deg = 20.0 - 6.0 * j;
    c.secondary_deg = -4.0;
    c.sid_mm = 1190;
    c.sod_mm = 795;
    c.fluoro_on = true;
    s.carm.push_back(c);
  }
  session::write_session(dir / "original", s, images);
  const session::Session original = session::read_session(dir / "original");

  const std::string serial = "EVARREC" + std::to_string(::getpid() % 100000);
  sim::GigEFrameServer camera(serial);
  const std::string link = (dir / "ttyCARM").string();
  sim::SerialCArmServer carm_link(link);

  const fs::path out = dir / "recorded";
  // The replay loops over the session until the recording is done, so however long the
  // command takes to find the camera and open the link, whole loops get recorded.
  session::SessionReplay replay(original, {1.0, 0});
  replay.carm().start([&](const evar::acquisition::CArmState& st) { carm_link.send(st); }, nullptr, nullptr);
  replay.frames().start([&](const evar::acquisition::Frame& f) { camera.show(f); }, nullptr);
  const int code = evar::app::run_cli({"record", "--camera", serial, "--width", "128", "--height", "96", "--fps", "40",
                                       "--carm", "serial:" + link + ",baud=115200", "--scene",
                                       (dir / "plan" / "scene.json").string(), "--registration",
                                       (dir / "plan" / "registration.json").string(), "--pixel-spacing", "0.154",
                                       "--seconds", "6", "--out", out.string()});
  replay.frames().stop();
  replay.carm().stop();
  ASSERT_EQ(code, 0);

  const session::Session back = session::read_session(out);
  EXPECT_EQ(back.detector.cols, 128);
  EXPECT_DOUBLE_EQ(back.detector.col_spacing_mm, 0.154);
  EXPECT_DOUBLE_EQ(back.ct_to_carm(0, 3), -5.0);
  ASSERT_GE(back.carm.size(), 8u);
  for (const auto& c : back.carm) {  // every recorded state is one the C-arm sent
    bool known = false;
    for (const auto& o : original.carm) known |= std::abs(c.primary_deg - o.primary_deg) < 0.0005;
    EXPECT_TRUE(known) << c.primary_deg;
  }

  // The camera shows each picture until the next (at 40 fps), so the recording holds the
  // original frames in order, each repeated, loop after loop; blank frames may come first.
  // Where a frame is seen coming in (the step from its predecessor, so within a camera
  // period of when it was shown; the recording may start in the middle of a picture) and
  // the C-arm link was already up, its geometry is checked: `arrivals[k]` are those frames.
  std::vector<std::vector<std::size_t>> arrivals(8);
  int last = -1;
  std::size_t unknown = 0;
  for (std::size_t i = 0; i < back.frames.size(); ++i) {
    const cv::Mat img = session::read_session_frame(back, i);
    int which = -1;
    for (int k = 0; k < 8; ++k)
      if (same_pixels(img, images[static_cast<std::size_t>(k)])) which = k;
    if (which < 0) {
      unknown += cv::countNonZero(img) > 0;
      continue;
    }
    if (last >= 0) {
      EXPECT_TRUE(which == last || which == (last + 1) % 8) << "frame " << which << " after " << last << " at " << i;
    }
    const bool arrives = last >= 0 && which == (last + 1) % 8;
    last = which;
    if (arrives && back.frames[i].timestamp_ns > back.carm.front().timestamp_ns)
      arrivals[static_cast<std::size_t>(which)].push_back(i);
  }
  EXPECT_EQ(unknown, 0u) << "recorded frames that are no original frame (torn or corrupted)";

  // The geometry in force when a frame arrived is the one in force in the original. The
  // two streams are replayed by two threads of this test, 100 ms either side of a C-arm
  // change; on a loaded machine (CI runs two sanitized suites' tests at once) one of them
  // can be late by that much, which shifts that one arrival by one state. So: every arrival
  // carries the original state or a neighbour, and in every loop but at most one per frame
  // it is the original's. A recorder pairing frames with the wrong state (an offset
  // between the two clocks of 100 ms or more, a state taken before its time) fails each.
  constexpr double kStepDeg = 6.0;  // between consecutive C-arm states above
  for (int k = 0; k < 8; ++k) {
    const auto& seen = arrivals[static_cast<std::size_t>(k)];
    ASSERT_FALSE(seen.empty()) << "original frame " << k << " was never recorded with geometry";
    const auto* was = session::carm_at(original, original.frames[static_cast<std::size_t>(k)].timestamp_ns);
    ASSERT_TRUE(was);
    std::size_t right = 0;
    std::string said;
    for (const std::size_t i : seen) {
      const std::int64_t t = back.frames[i].timestamp_ns;
      const auto* now = session::carm_at(back, t);
      ASSERT_TRUE(now);
      right += std::abs(now->primary_deg - was->primary_deg) < 0.0005;
      // Said on failure: how far the frame was recorded from the C-arm changes around it
      // (about 100 ms each way in the original; the camera period adds up to 25 ms).
      const auto next = std::upper_bound(back.carm.begin(), back.carm.end(), t,
                                         [](std::int64_t a, const session::CArmSample& c) { return a < c.timestamp_ns; });
      said += "\n  recorded as frame " + std::to_string(i) + " with " + std::to_string(now->primary_deg) + " deg, " +
              std::to_string(1e-6 * static_cast<double>(t - now->timestamp_ns)) + " ms after the state in force and " +
              std::to_string(next == back.carm.end() ? -1.0 : 1e-6 * static_cast<double>(next->timestamp_ns - t)) +
              " ms before the next";
      EXPECT_LE(std::abs(now->primary_deg - was->primary_deg), kStepDeg + 0.0005)
          << "frame " << k << " (" << was->primary_deg << " deg in the original):" << said;
    }
    EXPECT_GE(right + 1, seen.size()) << "frame " << k << " (" << was->primary_deg << " deg in the original):" << said;
    EXPECT_GE(right, 1u) << "frame " << k << " (" << was->primary_deg << " deg in the original):" << said;
  }
  const auto report = nlohmann::json::parse(std::ifstream(out / "record_report.json"));
  EXPECT_EQ(report["frames"]["written"].get<std::size_t>(), back.frames.size());
  EXPECT_EQ(report["frames"]["not_recorded_disk_behind"], 0);
  EXPECT_EQ(report["frames"]["statistics"]["dropped"], 0) << report.dump(2);
  fs::remove_all(dir);
}

TEST(DevicesCommand, ListsTheGigECameraOnLoopback) {
  const std::string serial = "EVARDEV" + std::to_string(::getpid() % 100000);
  sim::GigEFrameServer camera(serial);
  testing::internal::CaptureStdout();
  ASSERT_EQ(evar::app::run_cli({"devices", "--json"}), 0);
  const auto j = nlohmann::json::parse(testing::internal::GetCapturedStdout());
  bool found = false;
  for (const auto& c : j["gige_cameras"]) found |= c["serial"] == serial && c["address"] == "127.0.0.1";
  EXPECT_TRUE(found) << j.dump(2);
  EXPECT_TRUE(j["v4l2_devices"].is_array());
  EXPECT_TRUE(j["serial_ports"].is_array());
  EXPECT_TRUE(j["usb_devices"].is_array());
}
