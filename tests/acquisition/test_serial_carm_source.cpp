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
#include "evar/acquisition/serial_carm_source.hpp"
#include "evar/acquisition/serial_ports.hpp"
#include "evar/sim/pseudo_terminal.hpp"
#include "support/stream_log.hpp"

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

// The C-arm states a source delivered, beside its stream notices.
struct Recorder : evar::test::StreamLog {
  void on_state(const acq::CArmState& s) {
    record([&] { states.push_back(s); });
  }
  std::vector<acq::CArmState> states;
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
                 [this](acq::StreamState s, const std::string& r) { rec.on_stream(s, r); },
                 [this](const acq::LinkNotice& n) { rec.on_notice(n); });
  }
  // The source has the port open (it says so) before the peer sends.
  void wait_open() {
    ASSERT_TRUE(rec.wait([&] { return rec.said({"waiting for the first geometry sample"}); }));
  }
};

}  // namespace

TEST_F(SerialCArmLink, SamplesArriveInOrderWithTheirValues) {
  evar::sim::PseudoTerminal pty(link_path);
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
  evar::sim::PseudoTerminal pty(link_path);
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
  // Said as news, not as a change of state: the link streams on.
  EXPECT_TRUE(rec.wait([&] { return rec.noticed({"C-arm link serial ", "bad frames so far"}); }));
  std::lock_guard lock(rec.mutex);  // the source runs on
  EXPECT_FALSE(rec.said({"bad frames"}));
  EXPECT_EQ(rec.notices.front().kind, acq::LinkNotice::Kind::BadFrames);
}

TEST_F(SerialCArmLink, ASilentLinkIsReportedStalledAndRecovers) {
  evar::sim::PseudoTerminal pty(link_path);
  acq::SerialCArmSource source(options());
  start(source);
  wait_open();
  pty.write(wire::encode(sample(0)));
  ASSERT_TRUE(rec.wait([&] { return source.state() == acq::StreamState::Streaming; }));
  ASSERT_TRUE(rec.wait([&] { return rec.saw(acq::StreamState::Stalled); }));
  std::size_t mark = 0;
  rec.record([&] { mark = rec.streams.size(); });
  pty.write(wire::encode(sample(1)));
  ASSERT_TRUE(rec.wait([&] { return rec.saw(acq::StreamState::Streaming, mark); }));
}

TEST_F(SerialCArmLink, AHangupIsReportedAndTheLinkReconnectsOnItsOwn) {
  acq::SerialCArmSource source(options());
  {
    evar::sim::PseudoTerminal pty(link_path);
    start(source);
    wait_open();
    for (std::uint16_t i : {0, 1, 2, 5, 6}) pty.write(wire::encode(sample(i)));  // 3 and 4 lost on the way
    ASSERT_TRUE(rec.wait([&] { return rec.states.size() == 5; }));
  }  // the adapter goes away: both ends closed
  ASSERT_TRUE(rec.wait([&] { return rec.saw(acq::StreamState::Disconnected); }));
  // While nobody is there the source keeps trying and says why.
  const auto connecting = acq::StreamState::Connecting;
  ASSERT_TRUE(rec.wait([&] { return rec.said({link_path.c_str(), "retrying"}, &connecting); }));
  evar::sim::PseudoTerminal again(link_path);  // a new pty behind the same name
  ASSERT_TRUE(rec.wait([&] { return source.statistics().connections == 2; }));
  for (std::uint16_t i = 5; i < 10; ++i) {
    auto m = sample(i);
    m.sequence = static_cast<std::uint16_t>(30000 + i);
    again.write(wire::encode(m));
  }
  ASSERT_TRUE(rec.wait([&] { return rec.states.size() == 10; }));
  EXPECT_EQ(source.statistics().disconnections, 1u);
  EXPECT_EQ(rec.states.back().device_time_ns, 9'000'000'000LL);
  // The new adapter numbered its messages from 30000: a new link, not 29 995 lost samples;
  // the two lost on the first link are still counted (before the fix a reconnect
  // forgot them), and every message of both links is.
  EXPECT_EQ(source.statistics().link.sequence.dropped, 2u);
  EXPECT_EQ(source.statistics().link.sequence.received, 10u);
}

TEST_F(SerialCArmLink, AMissingOrWrongDeviceIsReportedNotThrown) {
  acq::SerialCArmSource missing(options());
  start(missing);
  const auto connecting = acq::StreamState::Connecting;
  ASSERT_TRUE(rec.wait([&] { return rec.said({"open failed"}, &connecting); }));
  missing.stop();

  std::ofstream(link_path) << "not a terminal";
  Recorder other;
  acq::SerialCArmSource file(options());
  file.start([](const acq::CArmState&) {}, [&](acq::StreamState s, const std::string& r) { other.on_stream(s, r); },
             nullptr);
  ASSERT_TRUE(other.wait([&] { return other.said({"tcgetattr"}); }));
  file.stop();

  acq::SerialLinkOptions bad = options();
  bad.settings.baud = 12345;
  EXPECT_THROW(acq::SerialCArmSource{bad}, std::invalid_argument);
  // Refused at once, not by the link thread (which would retry it as a missing device).
  acq::SerialLinkOptions three_stop_bits = options();
  three_stop_bits.settings.stop_bits = 3;
  EXPECT_THROW(acq::SerialCArmSource{three_stop_bits}, std::invalid_argument);
}

TEST(CArmSerialSettings, ParityNamesParse) {
  EXPECT_EQ(acq::parse_parity("even"), acq::Parity::Even);
  EXPECT_THROW(acq::parse_parity("mark"), std::invalid_argument);
  EXPECT_TRUE(acq::is_supported_baud(921600));
  EXPECT_FALSE(acq::is_supported_baud(100000));
}

TEST(SerialPorts, ListsAdaptersInNumberOrderWithTheirStableNames) {
  const auto dev = std::filesystem::temp_directory_path() / ("evar-dev-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dev / "serial" / "by-id");
  for (const char* n : {"ttyUSB10", "ttyUSB2", "ttyACM0", "ttyS0", "ttyS1", "tty1", "video0"}) std::ofstream(dev / n).put('\n');
  std::filesystem::create_symlink("../../ttyUSB2", dev / "serial" / "by-id" / "usb-FTDI_FT232R_A1B2C3-if00-port0");
  // sysfs: ttyS0 is an empty slot (type 0), ttyS1 a 16550A (type 4).
  const auto sys = dev / "sys-class-tty";
  std::filesystem::create_directories(sys / "ttyS0");
  std::filesystem::create_directories(sys / "ttyS1");
  std::ofstream(sys / "ttyS0" / "type") << "0\n";
  std::ofstream(sys / "ttyS1" / "type") << "4\n";
  const auto ports = acq::list_serial_ports(dev, sys);
  std::filesystem::remove_all(dev);
  ASSERT_EQ(ports.size(), 4u);
  EXPECT_EQ(std::filesystem::path(ports[0].path).filename(), "ttyACM0");
  EXPECT_EQ(ports[0].kind, "USB CDC ACM");
  EXPECT_EQ(std::filesystem::path(ports[1].path).filename(), "ttyS1");
  EXPECT_EQ(ports[1].kind, "UART");
  EXPECT_EQ(std::filesystem::path(ports[2].path).filename(), "ttyUSB2");
  ASSERT_EQ(ports[2].by_id.size(), 1u);
  EXPECT_NE(ports[2].by_id[0].find("usb-FTDI_FT232R_A1B2C3"), std::string::npos);
  EXPECT_EQ(std::filesystem::path(ports[3].path).filename(), "ttyUSB10");
  EXPECT_TRUE(ports[3].by_id.empty());
}
