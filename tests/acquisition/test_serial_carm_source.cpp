// Hardware-in-the-loop: the real termios serial code against a pseudo-terminal peer that
// speaks the C-arm link protocol, as a C-arm-side adapter would.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "evar/acquisition/carm_link_protocol.hpp"
#include "evar/acquisition/pseudo_terminal.hpp"
#include "evar/acquisition/serial_carm_source.hpp"

namespace acq = evar::acquisition;
namespace wire = acq::carm_link;
using namespace std::chrono_literals;

namespace {

wire::GeometryMessage sample(std::uint16_t seq) {
  wire::GeometryMessage m;
  m.sequence = seq;
  m.state.device_time_ns = 1'000'000'000LL * seq;
  m.state.primary_deg = seq * 0.25;
  m.state.secondary_deg = -10;
  m.state.sid_mm = 1200;
  m.state.sod_mm = 800;
  m.state.fluoro_on = true;
  return m;
}

// Collects what a source reports; tests wait on conditions, never on fixed sleeps.
class Recorder {
 public:
  void on_state(const acq::CArmState& s) {
    std::lock_guard lock(m_);
    states.push_back(s);
    cv_.notify_all();
  }
  void on_stream(acq::StreamState s, const std::string& reason) {
    std::lock_guard lock(m_);
    streams.emplace_back(s, reason);
    cv_.notify_all();
  }
  bool wait(const std::function<bool()>& done, std::chrono::milliseconds limit = 10s) {
    std::unique_lock lock(m_);
    return cv_.wait_for(lock, limit, done);
  }
  bool saw(acq::StreamState s, std::size_t from = 0) const {
    for (std::size_t i = from; i < streams.size(); ++i)
      if (streams[i].first == s) return true;
    return false;
  }
  std::vector<acq::CArmState> states;
  std::vector<std::pair<acq::StreamState, std::string>> streams;

 private:
  std::mutex m_;
  std::condition_variable cv_;
};

struct SerialCArmLink : ::testing::Test {
  std::filesystem::path dir = std::filesystem::temp_directory_path() /
                              ("evar-serial-" + std::to_string(::getpid()) + "-" +
                               ::testing::UnitTest::GetInstance()->current_test_info()->name());
  std::string link_path;
  Recorder rec;
  void SetUp() override {
    std::filesystem::create_directories(dir);
    link_path = (dir / "ttyCARM").string();
  }
  void TearDown() override { std::filesystem::remove_all(dir); }
  acq::SerialLinkOptions options() const {
    acq::SerialLinkOptions o;
    o.path = link_path;
    o.reconnect_interval = 20ms;
    o.stale_after = 300ms;
    return o;
  }
  void start(acq::SerialCArmSource& source) {
    source.start([this](const acq::CArmState& s) { rec.on_state(s); },
                 [this](acq::StreamState s, const std::string& r) { rec.on_stream(s, r); });
  }
  // The source has the port open (it says so) before the peer sends.
  void wait_open() {
    ASSERT_TRUE(rec.wait([&] {
      for (const auto& [s, r] : rec.streams)
        if (r.find("waiting for the first geometry sample") != std::string::npos) return true;
      return false;
    }));
  }
};

}  // namespace

TEST_F(SerialCArmLink, SamplesArriveInOrderWithTheirValues) {
  acq::PseudoTerminal pty(link_path);
  acq::SerialCArmSource source(options());
  start(source);
  wait_open();
  for (std::uint16_t i = 0; i < 100; ++i) pty.write(wire::encode(sample(i)));
  ASSERT_TRUE(rec.wait([&] { return rec.states.size() == 100; })) << rec.states.size();
  for (std::size_t i = 0; i < 100; ++i) {
    EXPECT_EQ(rec.states[i].device_time_ns, 1'000'000'000LL * static_cast<std::int64_t>(i));
    EXPECT_NEAR(rec.states[i].primary_deg, i * 0.25, 0.0005);
  }
  EXPECT_TRUE(rec.wait([&] { return rec.saw(acq::StreamState::Streaming); }));
  source.stop();
  EXPECT_EQ(source.state(), acq::StreamState::Stopped);
  const auto st = source.statistics();
  EXPECT_EQ(st.link.geometry, 100u);
  EXPECT_EQ(st.link.errors(), 0u);
  EXPECT_EQ(st.connections, 1u);
}

TEST_F(SerialCArmLink, GarbageBitFlipsAndTornFramesAreCountedAndTheLinkGoesOn) {
  acq::PseudoTerminal pty(link_path);
  acq::SerialCArmSource source(options());
  start(source);
  wait_open();
  std::mt19937 rng(5);
  std::size_t expected = 0, bad = 0;
  for (std::uint16_t i = 0; i < 60; ++i) {
    auto bytes = wire::encode(sample(i));
    switch (i % 4) {
      case 0: {  // line noise before the frame
        std::vector<std::uint8_t> junk(1 + rng() % 30);
        for (auto& b : junk) b = static_cast<std::uint8_t>(1 + rng() % 255);
        pty.write(junk);
        ++bad;
        ++expected;
        break;
      }
      case 1:  // a bit flip inside the frame
        bytes[5] ^= 0x10;
        ++bad;
        break;
      case 2:  // torn: the first half only
        bytes.resize(bytes.size() / 2);
        ++bad;
        break;
      default:
        ++expected;
    }
    pty.write(bytes);
  }
  pty.write(wire::encode(sample(60)));  // ends the last torn frame, if any
  ++expected;
  ASSERT_TRUE(rec.wait([&] { return rec.states.size() == expected; })) << rec.states.size() << " of " << expected;
  const auto st = source.statistics();
  EXPECT_EQ(st.link.errors(), bad);
  EXPECT_EQ(st.link.crc_errors + st.link.framing_errors, bad);
  EXPECT_EQ(st.link.sequence.dropped, 60u - (expected - 1));  // the lost samples are known
  EXPECT_FALSE(st.last_error.empty());
  EXPECT_TRUE(rec.wait([&] {
    for (const auto& [s, r] : rec.streams)
      if (r.find("bad frames so far") != std::string::npos) return true;
    return false;
  }));
}

TEST_F(SerialCArmLink, ASilentLinkIsReportedStalledAndRecovers) {
  acq::PseudoTerminal pty(link_path);
  acq::SerialCArmSource source(options());
  start(source);
  wait_open();
  pty.write(wire::encode(sample(0)));
  ASSERT_TRUE(rec.wait([&] { return source.state() == acq::StreamState::Streaming; }));
  ASSERT_TRUE(rec.wait([&] { return rec.saw(acq::StreamState::Stalled); }));
  std::size_t mark = 0;
  rec.wait([&] {
    mark = rec.streams.size();
    return true;
  });
  pty.write(wire::encode(sample(1)));
  ASSERT_TRUE(rec.wait([&] { return rec.saw(acq::StreamState::Streaming, mark); }));
}

TEST_F(SerialCArmLink, AHangupIsReportedAndTheLinkReconnectsOnItsOwn) {
  acq::SerialCArmSource source(options());
  {
    acq::PseudoTerminal pty(link_path);
    start(source);
    wait_open();
    for (std::uint16_t i = 0; i < 5; ++i) pty.write(wire::encode(sample(i)));
    ASSERT_TRUE(rec.wait([&] { return rec.states.size() == 5; }));
  }  // the adapter goes away: both ends closed
  ASSERT_TRUE(rec.wait([&] { return rec.saw(acq::StreamState::Disconnected); }));
  // While nobody is there the source keeps trying and says why.
  ASSERT_TRUE(rec.wait([&] {
    for (const auto& [s, r] : rec.streams)
      if (s == acq::StreamState::Connecting && r.find(link_path) != std::string::npos && r.find("retrying") != std::string::npos)
        return true;
    return false;
  }));
  acq::PseudoTerminal again(link_path);  // a new pty behind the same name
  ASSERT_TRUE(rec.wait([&] { return source.statistics().connections == 2; }));
  for (std::uint16_t i = 5; i < 10; ++i) {
    auto m = sample(i);
    m.sequence = static_cast<std::uint16_t>(30000 + i);
    again.write(wire::encode(m));
  }
  ASSERT_TRUE(rec.wait([&] { return rec.states.size() == 10; }));
  EXPECT_EQ(source.statistics().disconnections, 1u);
  EXPECT_EQ(rec.states.back().device_time_ns, 9'000'000'000LL);
  // The new adapter numbered its messages from 30000: a new link, not 29 995 lost samples.
  EXPECT_EQ(source.statistics().link.sequence.dropped, 0u);
}

TEST_F(SerialCArmLink, AMissingOrWrongDeviceIsReportedNotThrown) {
  acq::SerialCArmSource missing(options());
  start(missing);
  ASSERT_TRUE(rec.wait([&] {
    for (const auto& [s, r] : rec.streams)
      if (s == acq::StreamState::Connecting && r.find("open failed") != std::string::npos) return true;
    return false;
  }));
  missing.stop();

  std::ofstream(link_path) << "not a terminal";
  Recorder other;
  acq::SerialCArmSource file(options());
  file.start([](const acq::CArmState&) {}, [&](acq::StreamState s, const std::string& r) { other.on_stream(s, r); });
  ASSERT_TRUE(other.wait([&] {
    for (const auto& [s, r] : other.streams)
      if (r.find("tcgetattr") != std::string::npos) return true;
    return false;
  }));
  file.stop();

  acq::SerialLinkOptions bad = options();
  bad.settings.baud = 12345;
  EXPECT_THROW(acq::SerialCArmSource{bad}, std::invalid_argument);
}

TEST(CArmSerialSettings, ParityNamesParse) {
  EXPECT_EQ(acq::parse_parity("even"), acq::Parity::Even);
  EXPECT_THROW(acq::parse_parity("mark"), std::invalid_argument);
  EXPECT_TRUE(acq::is_supported_baud(921600));
  EXPECT_FALSE(acq::is_supported_baud(100000));
}
