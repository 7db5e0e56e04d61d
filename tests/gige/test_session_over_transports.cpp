// A recorded session played over the real transports and received by the real sources:
// frames through a GigE Vision camera on 127.0.0.1 into the Aravis source, C-arm states
// through the serial protocol on a pseudo-terminal into the termios source.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <opencv2/core.hpp>

#include "evar/acquisition/gige_camera_source.hpp"
#include "evar/acquisition/serial_carm_source.hpp"
#include "evar/session/session_replay.hpp"
#include "evar/sim/gige_frame_server.hpp"
#include "evar/sim/serial_carm_server.hpp"
#include "support/ramp_frames.hpp"
#include "support/stream_log.hpp"

namespace acq = evar::acquisition;
namespace sim = evar::sim;
namespace session = evar::session;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

TEST(SessionOverTransports, EveryFrameAndEverySampleArrivesThroughTheRealSources) {
  const fs::path dir = fs::path(testing::TempDir()) / ("evar_transport_session_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  session::Session s;
  s.scene = "scene.json";
  s.detector = {128, 96, 0.3, 0.3};  // Aravis 0.8.26's fake camera loses packets of frames under ~6 KB
  const std::vector<cv::Mat> images = evar::test::add_ramp_frames(s, 8, 150'000'000LL, {4000, 61, 7, 1});
  for (int k = 0; k < 6; ++k) {
    session::CArmSample c;
    c.timestamp_ns = 1'000'000'000LL + k * 200'000'000LL;
    c.primary_deg = -30.0 + 12.5 * k;
    c.secondary_deg = 5.0;
    c.sid_mm = 1200;
    c.sod_mm = 800;
    c.fluoro_on = true;
    c.moving = k % 2 == 1;
    s.carm.push_back(c);
  }
  session::write_session(dir, s, images);
  const session::Session session = session::read_session(dir);

  // The transports' far ends.
  const std::string serial = "EVARSES" + std::to_string(::getpid() % 100000);
  sim::GigEFrameServer camera(serial);
  sim::SerialCArmServer carm_link((dir / "ttyCARM").string());

  // The node's side: the real sources.
  evar::test::StreamLog video, carm;  // declared first: they outlive the sources
  std::vector<int> shown;             // under video's mutex: which session image each frame is
  std::size_t unknown = 0;
  std::vector<acq::CArmState> states;  // under carm's mutex
  acq::GigECameraOptions go;
  go.camera = serial;
  go.region = acq::Region{0, 0, 128, 96};
  go.frame_rate_hz = 40.0;
  acq::GigECameraSource gige(go);
  acq::SerialLinkOptions so;
  so.path = (dir / "ttyCARM").string();
  acq::SerialCArmSource serial_source(so);
  gige.start(
      [&](const acq::Frame& f) {
        int which = -1;
        for (int k = 0; k < 8; ++k)
          if (f.pixels.size() == 128u * 96u * 2u && std::memcmp(f.pixels.data(), images[static_cast<std::size_t>(k)].data, f.pixels.size()) == 0)
            which = k;
        bool blank = true;
        for (auto b : f.pixels) blank &= b == 0;
        video.record([&] {
          if (which < 0 && !blank) ++unknown;  // blank: the camera before the first replayed frame
          if (which >= 0) shown.push_back(which);
        });
      },
      [&](acq::StreamState st, const std::string& r) { video.on_stream(st, r); });
  serial_source.start(
      [&](const acq::CArmState& st) { carm.record([&] { states.push_back(st); }); },
      [&](acq::StreamState st, const std::string& r) { carm.on_stream(st, r); },
      [&](const acq::LinkNotice& n) { carm.on_notice(n); });
  ASSERT_TRUE(video.wait([&] { return video.saw(acq::StreamState::Streaming); }));
  ASSERT_TRUE(carm.wait([&] { return carm.said({"waiting for the first geometry sample"}); }));

  // The replay drives the far ends in real time.
  session::SessionReplay replay(session, {1.0, 1});
  replay.carm().start([&](const acq::CArmState& st) { carm_link.send(st); }, nullptr, nullptr);
  replay.frames().start([&](const acq::Frame& f) { camera.show(f); }, nullptr);
  ASSERT_TRUE(replay.wait(30s));
  std::this_thread::sleep_for(300ms);  // the last picture stays on; let a few frames of it arrive
  ASSERT_TRUE(carm.wait([&] { return states.size() == 6; }, 10s)) << states.size();
  gige.stop();
  serial_source.stop();  // no callback runs after these: the records are ours now

  EXPECT_EQ(unknown, 0u) << "frames that are no session frame (torn or corrupted)";
  ASSERT_FALSE(shown.empty());
  for (std::size_t i = 1; i < shown.size(); ++i) EXPECT_GE(shown[i], shown[i - 1]) << "out of order at " << i;
  for (int k = 0; k < 8; ++k) EXPECT_NE(std::find(shown.begin(), shown.end(), k), shown.end()) << "frame " << k << " never arrived";
  for (std::size_t k = 0; k < 6; ++k) {
    EXPECT_NEAR(states[k].primary_deg, -30.0 + 12.5 * static_cast<double>(k), 0.0005);
    EXPECT_EQ(states[k].moving, k % 2 == 1);
  }
  EXPECT_EQ(gige.gige_statistics().frames.dropped, 0u) << "stream: " << gige.gige_statistics().completed << " completed, " << gige.gige_statistics().failed << " failed, " << gige.gige_statistics().underruns << " underruns";
  EXPECT_EQ(serial_source.statistics().link.errors(), 0u);
  EXPECT_EQ(carm_link.dropped(), 0u);
  {
    std::lock_guard lock(carm.mutex);
    EXPECT_TRUE(carm.notices.empty()) << "a clean link gave a notice: " << carm.notices.front().text;
  }
  fs::remove_all(dir);
}
