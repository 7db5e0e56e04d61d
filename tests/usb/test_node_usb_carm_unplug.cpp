// The USB C-arm adapter unplugged and plugged back while the node runs: a replayed simulated
// session gives the node its frames (free-running, as from the C-arm's video out), and its C-arm states reach the node through the real
// libusb from an adapter emulated by umockdev (usb/emulated_carm_adapter.hpp). Mid-run the
// adapter is pulled for a while, then plugged back. The video goes on and the adapted model
// stays; the screen says the link is gone and the geometry stale; the log says each state
// once, however often the source looks for the adapter; and the link comes back by itself.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <mutex>
#include <optional>
#include <thread>

#include "evar/acquisition/carm_link_protocol.hpp"
#include "evar/acquisition/usb_carm_source.hpp"
#include "evar/node/live_node.hpp"
#include "evar/session/session_replay.hpp"
#include "evar/sim/session_generator.hpp"
#include "support/node_screen.hpp"
#include "usb/emulated_carm_adapter.hpp"

namespace {

using namespace evar;
using namespace std::chrono_literals;
namespace fs = std::filesystem;
namespace wire = acquisition::carm_link;
using test::count_of;
using test::ScreenLog;

// The C-arm's video out as a grabber sees it: the latest image the replay played, again at
// a fixed rate whether or not the replay has a new one (a replay alone pauses its frames
// between runs of fluoroscopy, which the node would rightly call a stalled video).
class FreeRunningVideo final : public acquisition::FrameSource {
 public:
  FreeRunningVideo(acquisition::FrameSource& replay, double fps) : replay_(replay), fps_(fps) {}
  ~FreeRunningVideo() override { stop(); }
  void start(FrameCallback on_frame, StateCallback on_state) override {
    replay_.start(
        [this](const acquisition::Frame& f) {
          std::lock_guard lock(mutex_);
          latest_ = f;
        },
        nullptr);
    on_ = true;
    thread_ = std::thread([this, on_frame = std::move(on_frame)] {
      const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(1s / fps_);
      for (auto next = std::chrono::steady_clock::now(); on_; next += period) {
        std::this_thread::sleep_until(next);
        acquisition::Frame f;
        {
          std::lock_guard lock(mutex_);
          if (!latest_) continue;
          f = *latest_;
        }
        f.sequence = sent_;
        f.host_arrival = f.device_time_on_host = std::chrono::steady_clock::now();
        f.device_time_ns = f.host_arrival.time_since_epoch().count();
        f.device_clock = false;
        on_frame(f);
        ++sent_;
      }
    });
    if (on_state) on_state(acquisition::StreamState::Streaming, description());
  }
  void stop() override {
    if (!thread_.joinable()) return;
    on_ = false;
    thread_.join();
    replay_.stop();
  }
  acquisition::StreamState state() const override { return acquisition::StreamState::Streaming; }
  acquisition::SequenceStats statistics() const override { return {sent_.load(), 0, 0, 0, 0}; }
  std::string description() const override { return "the replay's latest image, free-running"; }

 private:
  acquisition::FrameSource& replay_;
  double fps_;
  std::mutex mutex_;
  std::optional<acquisition::Frame> latest_;
  std::atomic<bool> on_{false};
  std::atomic<std::uint64_t> sent_{0};
  std::thread thread_;
};

TEST(NodeOverUsbCArmLink, AnUnpluggedAdapterIsShownAndSaidOnceTheModelKeptAndTheLinkBackByItself) {
  const fs::path dir = fs::temp_directory_path() / ("evar_node_usb_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  sim::SessionPlan plan;
  plan.seed = 1;
  plan.detector_px = 512;
  plan.pixel_spacing_mm = 0.6;
  const sim::GeneratedSession generated = sim::generate_session(plan, dir / "session");
  const session::Session& session = generated.session;
  const geometry::Scene scene = geometry::load_scene(dir / "session" / session.scene);

  // The adapter sends each of the session's C-arm states while it is plugged in; pulled, it
  // sends nothing (and keeps nothing for later).
  test::EmulatedAdapter adapter;
  adapter.plug();
  std::mutex plug_mutex;
  bool plugged = true;
  std::uint16_t sequence = 0;
  session::SessionReplay replay(session, {1.0, 0});
  replay.carm().start(
      [&](const acquisition::CArmState& s) {
        std::lock_guard lock(plug_mutex);
        if (!plugged) return;
        wire::GeometryMessage m;
        m.sequence = sequence++;
        m.state = s;
        adapter.send(wire::encode(m));
      },
      nullptr, nullptr);
  const auto pull = [&] {
    std::lock_guard lock(plug_mutex);
    plugged = false;
    adapter.unplug();
  };
  const auto plug_back = [&] {
    std::lock_guard lock(plug_mutex);
    adapter.plug();
    plugged = true;
  };

  // The node's side, as `evarnode run --config` makes it for `"carm": "usb:1209:ea01"`.
  acquisition::UsbLinkOptions uo;
  uo.device = {test::kVendor, test::kProduct, ""};
  acquisition::UsbCArmSource carm(uo);
  test::LogCapture log;
  auto screen_sink = std::make_unique<ScreenLog>();
  ScreenLog& screen = *screen_sink;
  std::vector<std::unique_ptr<node::OutputSink>> sinks;
  sinks.push_back(std::move(screen_sink));
  node::NodeOptions o;
  o.detector = session.detector;
  o.registration = session.ct_to_carm;
  node::LiveNode node(scene, o, std::move(sinks));
  FreeRunningVideo video(replay.frames(), plan.fluoro_fps);
  node.start(video, carm);

  // 1. The node adapts its model from the session's views.
  const std::size_t adapted =
      screen.wait_for(0, [](const ScreenLog::Shown& f) { return f.version >= 1 && !f.held; }, 120s);
  ASSERT_LT(adapted, screen.size()) << "no adapted model within 2 min: " << node.statistics().last_failure;

  // 2. The adapter is pulled. The screen says the link is gone; 45 more frames (3 s at the
  //    session's 15 frames a second, a dozen looks for the adapter) come meanwhile.
  const std::size_t pulled = screen.size();
  pull();
  const std::size_t said = screen.wait_for(
      pulled, [](const ScreenLog::Shown& f) { return ScreenLog::alert(f, "C-arm link disconnected"); }, 30s);
  ASSERT_LT(said, screen.size()) << "no frame said the C-arm link was disconnected";
  const std::size_t looking = screen.wait_for(
      said, [](const ScreenLog::Shown& f) { return ScreenLog::alert(f, "C-arm link connecting"); }, 30s);
  ASSERT_LT(looking, screen.size()) << "no frame said the source looks for the adapter";
  ASSERT_TRUE(screen.wait_until_shown(pulled + 46, 30s))
      << "the video stopped while the adapter was away";
  const std::size_t replugged = screen.size();
  const auto looks_before = carm.statistics().connections;
  plug_back();

  // 3. Plugged back: the link streams again and the roadmap comes back without help.
  const std::size_t back = screen.wait_for(
      replugged,
      [](const ScreenLog::Shown& f) {
        return !f.held && f.roadmap && !ScreenLog::carm_link_down(f) && !ScreenLog::alert(f, "stale");
      },
      30s);
  ASSERT_LT(back, screen.size()) << "the C-arm link did not come back on its own";
  ASSERT_TRUE(screen.wait_until_shown(back + 31, 30s))
      << "the frames stopped after the adapter came back";

  node.stop();  // stops the video and the replay's frames with it
  replay.carm().stop();
  const std::string text = log.text();
  const acquisition::CArmLinkStatistics link_stats = carm.statistics();
  const std::vector<ScreenLog::Shown>& shown = screen.frames;

  // (a, b) The video went on, never held, and the adapted model stayed on every frame.
  for (std::size_t i = adapted; i < shown.size(); ++i) {
    ASSERT_GE(shown[i].version, 1u) << "frame " << i << " went back to the preoperative model";
    ASSERT_FALSE(shown[i].held) << "frame " << i << " was held: the video stopped";
  }
  // (c) While the adapter was away, frames said the link was gone and the geometry stale,
  // with its age; none said the link was fine.
  bool stale_said = false;
  for (std::size_t i = said; i < replugged; ++i) {
    EXPECT_TRUE(ScreenLog::carm_link_down(shown[i])) << "frame " << i << " of the outage does not say so";
    stale_said |= ScreenLog::alert(shown[i], "C-arm geometry stale") && ScreenLog::line(shown[i], "s old");
  }
  EXPECT_TRUE(stale_said) << "no frame of the outage said the geometry was stale";
  EXPECT_EQ(looks_before, 1u) << "connected while it was unplugged";
  // (e) One outage, one reconnection.
  EXPECT_EQ(link_stats.connections, 2u);
  EXPECT_EQ(link_stats.disconnections, 1u);
  // (d) Each state of the link said once from the pull on, however long the adapter was
  // away: lost; looking for it; found, waiting for a sample; resolved by the first sample.
  const auto lost_at = text.find("] C-arm link disconnected");
  ASSERT_NE(lost_at, std::string::npos) << text;
  const std::string since = text.substr(lost_at);
  EXPECT_EQ(count_of(since, "] C-arm link disconnected"), 1u) << since;
  // Looking for it: with hotplug events (as here), "waiting for it to be plugged in", else
  // "looking again every 250 ms"; either is said once, not once a look.
  EXPECT_EQ(count_of(since, "; waiting for it to be plugged in") + count_of(since, "; looking again every"), 1u) << since;
  EXPECT_EQ(count_of(since, "] C-arm link connecting"), 2u) << since;
  EXPECT_EQ(count_of(since, "resolved: C-arm link"), 1u) << since;
  fs::remove_all(dir);
}

}  // namespace
