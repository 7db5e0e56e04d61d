// The USB C-arm link through the real libusb against a USB device emulated by umockdev
// (usb/emulated_carm_adapter.hpp), carrying C-arm link frames on a bulk IN endpoint. This
// program must run with umockdev's preload library; main() re-executes itself under it
// (usb/umockdev_main.cpp).
#include <gtest/gtest.h>

#include <chrono>
#include <mutex>
#include <string>
#include <vector>

#include "evar/acquisition/carm_link_protocol.hpp"
#include "evar/acquisition/usb_carm_source.hpp"
#include "support/stream_log.hpp"
#include "usb/emulated_carm_adapter.hpp"

namespace acq = evar::acquisition;
namespace wire = acq::carm_link;
using namespace std::chrono_literals;
using evar::test::EmulatedAdapter;
using evar::test::kProduct;
using evar::test::kVendor;

namespace {

wire::GeometryMessage sample(std::uint16_t seq) {
  wire::GeometryMessage m;
  m.sequence = seq;
  m.state.device_time_ns = 1'000'000LL * seq;
  m.state.primary_deg = -30.0 + seq;
  m.state.secondary_deg = 12.5;
  m.state.sid_mm = 1195.0;
  m.state.sod_mm = 785.0;
  m.state.fluoro_on = true;
  return m;
}

struct Recorder : evar::test::StreamLog {
  std::vector<acq::CArmState> states;
  acq::CArmGeometrySource::StateCallback state_callback() {
    return [this](const acq::CArmState& s) { record([&] { states.push_back(s); }); };
  }
  acq::CArmGeometrySource::StreamCallback stream_callback() {
    return [this](acq::StreamState s, const std::string& r) { on_stream(s, r); };
  }
  acq::CArmGeometrySource::NoticeCallback notice_callback() {
    return [this](const acq::LinkNotice& n) { on_notice(n); };
  }
};

acq::UsbLinkOptions options() {
  acq::UsbLinkOptions o;
  o.device = {kVendor, kProduct, ""};
  o.reconnect_interval = 100ms;
  o.stale_after = 500ms;
  return o;
}

TEST(UsbDeviceId, ParsesLsusbStyleIdsAndNamesWhatIsWrong) {
  const auto id = acq::parse_usb_device_id("1209:EA01");
  EXPECT_EQ(id.vendor, 0x1209);
  EXPECT_EQ(id.product, 0xea01);
  EXPECT_TRUE(id.serial.empty());
  EXPECT_EQ(acq::parse_usb_device_id("1209:ea01:CARM-7").serial, "CARM-7");
  EXPECT_EQ(acq::to_string(acq::parse_usb_device_id("1209:ea01:CARM-7")), "1209:ea01:CARM-7");
  for (const char* bad : {"1209", "1209:", "12345:0001", "12g9:0001", ":0001", "1209:0001:"}) {
    try {
      acq::parse_usb_device_id(bad);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
}

TEST(UsbEndpointChoice, TakesTheFirstReadableInEndpointOrTheOneAskedFor) {
  using T = acq::UsbTransferType;
  const std::vector<acq::UsbInterface> itfs = {
      {0, 0, {{0x82, T::Other, 192}, {0x02, T::Bulk, 512}}},          // isochronous audio, bulk OUT
      {1, 0, {{0x01, T::Bulk, 512}, {0x81, T::Bulk, 512}}},
      {2, 0, {{0x83, T::Interrupt, 16}}}};
  auto c = acq::choose_usb_endpoint(itfs, std::nullopt, std::nullopt);
  EXPECT_EQ(c.interface_number, 1);
  EXPECT_EQ(c.endpoint.address, 0x81);
  c = acq::choose_usb_endpoint(itfs, 2, std::nullopt);
  EXPECT_EQ(c.endpoint.address, 0x83);
  EXPECT_EQ(c.endpoint.type, T::Interrupt);
  c = acq::choose_usb_endpoint(itfs, std::nullopt, std::uint8_t{0x83});
  EXPECT_EQ(c.interface_number, 2);
  try {
    acq::choose_usb_endpoint(itfs, 0, std::nullopt);
    ADD_FAILURE() << "interface 0 has no readable endpoint";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("interface 0: 0x82 IN other 0x02 OUT bulk"), std::string::npos) << e.what();
  }
  EXPECT_THROW(acq::choose_usb_endpoint(itfs, std::nullopt, std::uint8_t{0x02}), std::runtime_error);
}

TEST(UsbDevices, ListsTheEmulatedAdapterWithItsEndpoints) {
  EmulatedAdapter adapter;
  adapter.plug();
  const auto all = acq::list_usb_devices();
  const auto mine = acq::list_usb_devices(acq::UsbDeviceId{kVendor, kProduct, ""});
  ASSERT_EQ(mine.size(), 1u);
  EXPECT_EQ(mine[0].bus, 1);
  EXPECT_EQ(mine[0].address, 2);
  ASSERT_EQ(mine[0].interfaces.size(), 1u);
  ASSERT_EQ(mine[0].interfaces[0].endpoints.size(), 2u);
  EXPECT_EQ(mine[0].interfaces[0].endpoints[0].address, 0x81);
  EXPECT_EQ(mine[0].interfaces[0].endpoints[0].type, acq::UsbTransferType::Bulk);
  EXPECT_EQ(mine[0].interfaces[0].endpoints[0].max_packet, 64);
  EXPECT_GE(all.size(), 1u);
  EXPECT_TRUE(acq::list_usb_devices(acq::UsbDeviceId{kVendor, 0xea02, ""}).empty());
}

TEST(UsbCArmSource, AMissingDeviceIsReportedAndLookedForAgain) {
  Recorder rec;
  acq::UsbCArmSource source(options());
  source.start(rec.state_callback(), rec.stream_callback(), rec.notice_callback());
  ASSERT_TRUE(rec.wait([&] { return rec.said({"no USB device 1209:ea01 is connected"}); }, 10s));
  EXPECT_EQ(source.state(), acq::StreamState::Connecting);
  source.stop();
  EXPECT_EQ(rec.streams.back().first, acq::StreamState::Stopped);
}

TEST(UsbCArmSource, ReadsGeometryThroughGarbageAndReconnectsAfterAnUnplug) {
  EmulatedAdapter adapter;
  adapter.plug();
  Recorder rec;
  acq::UsbCArmSource source(options());
  source.start(rec.state_callback(), rec.stream_callback(), rec.notice_callback());

  // Samples, then garbage and a bit-flipped frame, then more samples.
  std::vector<std::uint8_t> bytes;
  for (std::uint16_t s = 0; s < 20; ++s) {
    const auto f = wire::encode(sample(s));
    bytes.insert(bytes.end(), f.begin(), f.end());
  }
  for (int i = 0; i < 300; ++i) bytes.push_back(static_cast<std::uint8_t>(i * 37 + 11));
  auto flipped = wire::encode(sample(20));
  flipped[flipped.size() / 2] ^= 0x10;
  bytes.insert(bytes.end(), flipped.begin(), flipped.end());
  for (std::uint16_t s = 21; s < 40; ++s) {
    const auto f = wire::encode(sample(s));
    bytes.insert(bytes.end(), f.begin(), f.end());
  }
  adapter.send(bytes);
  ASSERT_TRUE(rec.wait([&] { return rec.states.size() >= 39; }, 20s)) << rec.states.size();
  EXPECT_EQ(source.state(), acq::StreamState::Streaming);
  {
    std::lock_guard lock(rec.mutex);
    ASSERT_EQ(rec.states.size(), 39u);
    EXPECT_NEAR(rec.states[0].primary_deg, -30.0, 1e-3);
    EXPECT_NEAR(rec.states[19].primary_deg, -11.0, 1e-3);
    EXPECT_NEAR(rec.states[20].primary_deg, -9.0, 1e-3) << "sample 20 was corrupted; 21 follows 19";
    EXPECT_NEAR(rec.states[38].sid_mm, 1195.0, 0.01);
  }
  auto stats = source.statistics();
  EXPECT_EQ(stats.link.geometry, 39u);
  EXPECT_GE(stats.link.crc_errors + stats.link.framing_errors, 1u);
  EXPECT_EQ(stats.connections, 1u);
  // The bad frames are news from a link that streams on, naming the adapter.
  EXPECT_TRUE(rec.wait([&] { return rec.noticed({"C-arm link USB 1209:ea01", "bad frames so far"}); }, 10s));

  // Pulled: reported, then found again when plugged back in.
  adapter.unplug();
  ASSERT_TRUE(rec.wait([&] { return rec.saw(acq::StreamState::Disconnected); }, 10s));
  adapter.plug();
  std::vector<std::uint8_t> more;
  for (std::uint16_t s = 100; s < 110; ++s) {
    const auto f = wire::encode(sample(s));
    more.insert(more.end(), f.begin(), f.end());
  }
  ASSERT_TRUE(rec.wait([&] { return rec.said({"open, waiting for the first geometry sample"}) && source.statistics().connections >= 2; }, 20s));
  adapter.send(more);
  ASSERT_TRUE(rec.wait([&] { return rec.states.size() >= 49; }, 20s)) << rec.states.size();
  EXPECT_NEAR(rec.states.back().primary_deg, 79.0, 1e-3);
  source.stop();
  stats = source.statistics();
  EXPECT_EQ(stats.connections, 2u);
  EXPECT_EQ(stats.disconnections, 1u);
}

}  // namespace

