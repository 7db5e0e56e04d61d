// The USB C-arm link through the real libusb against a USB device emulated by umockdev:
// the device appears in a mocked sysfs and /dev/bus/usb, and its usbfs ioctls
// (SUBMITURB, REAPURB, DISCARDURB, ...) are answered here as the C-arm adapter's firmware
// would, carrying C-arm link frames on a bulk IN endpoint. This program must run with
// umockdev's preload library; main() re-executes itself under it (as umockdev-wrapper does).
#include <gtest/gtest.h>
#include <linux/ioctl.h>
#include <linux/usbdevice_fs.h>
#include <umockdev.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <deque>
#include <mutex>
#include <string>
#include <vector>

#include "evar/acquisition/carm_link_protocol.hpp"
#include "evar/acquisition/usb_carm_source.hpp"
#include "support/stream_log.hpp"

namespace acq = evar::acquisition;
namespace wire = acq::carm_link;
using namespace std::chrono_literals;

namespace {

constexpr std::uint16_t kVendor = 0x1209, kProduct = 0xea01;  // pid.codes test ids

// Device and configuration descriptors: one vendor-specific interface with a bulk IN
// endpoint 0x81 and a bulk OUT endpoint 0x01, 64-byte packets (full speed).
std::string descriptor_hex() {
  const std::vector<std::uint8_t> d = {
      18, 1, 0x00, 0x02, 0, 0, 0, 64, kVendor & 0xFF, kVendor >> 8, kProduct & 0xFF, kProduct >> 8, 0x00, 0x01, 0, 0, 0, 1,
      9, 2, 32, 0, 1, 1, 0, 0x80, 50,
      9, 4, 0, 0, 2, 0xFF, 0, 0, 0,
      7, 5, 0x81, 0x02, 64, 0, 0,
      7, 5, 0x01, 0x02, 64, 0, 0};
  std::string s;
  char b[3];
  for (auto v : d) {
    std::snprintf(b, sizeof b, "%02x", v);
    s += b;
  }
  return s;
}

// The emulated C-arm adapter: what the host's URBs find on the bulk IN endpoint.
class EmulatedAdapter {
 public:
  EmulatedAdapter() {
    testbed_ = umockdev_testbed_new();
    handler_ = umockdev_ioctl_base_new();
    g_signal_connect_after(handler_, "handle-ioctl", G_CALLBACK(&EmulatedAdapter::on_ioctl), this);
  }
  ~EmulatedAdapter() {
    g_clear_object(&handler_);
    g_clear_object(&testbed_);
    for (auto* u : flying_) umockdev_ioctl_data_unref(u);
    for (auto* u : discarded_) umockdev_ioctl_data_unref(u);
  }

  void plug() {
    {
      std::lock_guard lock(mutex_);
      gone_ = false;
    }
    ASSERT_TRUE(umockdev_testbed_attach_ioctl(testbed_, kNode, handler_, nullptr));
    const std::string dev =
        "P: /devices/usb1/1-1\n"
        "N: bus/usb/001/002\n"
        "E: SUBSYSTEM=usb\nE: DRIVER=usb\nE: BUSNUM=001\nE: DEVNUM=002\n"
        "E: DEVNAME=/dev/bus/usb/001/002\nE: DEVTYPE=usb_device\n"
        "A: busnum=1\\n\nA: devnum=2\\n\nA: bConfigurationValue=1\\n\nA: speed=12\\n\n"
        "H: descriptors=" + descriptor_hex() + "\n";
    ASSERT_TRUE(umockdev_testbed_add_from_string(testbed_, dev.c_str(), nullptr));
  }
  void unplug() {
    {
      std::lock_guard lock(mutex_);
      gone_ = true;
      pending_.clear();
    }
    umockdev_testbed_remove_device(testbed_, "/sys/devices/usb1/1-1");
    umockdev_testbed_detach_ioctl(testbed_, kNode, nullptr);
  }
  void send(const std::vector<std::uint8_t>& bytes) {
    std::lock_guard lock(mutex_);
    pending_.insert(pending_.end(), bytes.begin(), bytes.end());
  }
  std::size_t unread() {
    std::lock_guard lock(mutex_);
    return pending_.size();
  }

 private:
  static constexpr const char* kNode = "/dev/bus/usb/001/002";

  static gboolean on_ioctl(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer self) {
    return static_cast<EmulatedAdapter*>(self)->handle(client);
  }

  gboolean handle(UMockdevIoctlClient* client) {
    std::lock_guard lock(mutex_);
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    switch (umockdev_ioctl_client_get_request(client)) {
      case USBDEVFS_GET_CAPABILITIES: {
        UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(guint32), nullptr);
        *reinterpret_cast<guint32*>(d->data) = USBDEVFS_CAP_BULK_CONTINUATION | USBDEVFS_CAP_NO_PACKET_SIZE_LIM |
                                               USBDEVFS_CAP_REAP_AFTER_DISCONNECT | USBDEVFS_CAP_ZERO_PACKET;
        umockdev_ioctl_data_unref(d);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      }
      case USBDEVFS_CLAIMINTERFACE:
      case USBDEVFS_RELEASEINTERFACE:
      case USBDEVFS_DISCONNECT_CLAIM:
      case USBDEVFS_CLEAR_HALT:
      case USBDEVFS_SETINTERFACE:
        umockdev_ioctl_client_complete(client, gone_ ? -1 : 0, gone_ ? ENODEV : 0);
        return TRUE;
      case USBDEVFS_SUBMITURB: {
        if (gone_) {
          umockdev_ioctl_client_complete(client, -1, ENODEV);
          return TRUE;
        }
        UMockdevIoctlData* urb = umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_urb), nullptr);
        const auto* u = reinterpret_cast<usbdevfs_urb*>(urb->data);
        if (u->type != USBDEVFS_URB_TYPE_BULK || u->endpoint != 0x81) {
          umockdev_ioctl_data_unref(urb);
          umockdev_ioctl_client_complete(client, -1, EINVAL);
          return TRUE;
        }
        flying_.push_back(urb);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      }
      case USBDEVFS_REAPURB:
      case USBDEVFS_REAPURBNDELAY: {
        UMockdevIoctlData* urb = nullptr;
        if (!discarded_.empty()) {  // a cancelled (timed-out) read comes back first
          urb = discarded_.front();
          discarded_.pop_front();
          reinterpret_cast<usbdevfs_urb*>(urb->data)->status = -ENOENT;
        } else if (!flying_.empty() && (gone_ || !pending_.empty())) {
          urb = flying_.front();
          flying_.pop_front();
          auto* u = reinterpret_cast<usbdevfs_urb*>(urb->data);
          if (gone_) {
            u->status = -ESHUTDOWN;
            u->actual_length = 0;
          } else {
            // Whole 64-byte packets, a short one ending the transfer, as a device sends.
            const std::size_t n = std::min<std::size_t>(pending_.size(), static_cast<std::size_t>(u->buffer_length));
            std::copy(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(n), static_cast<std::uint8_t*>(u->buffer));
            pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(n));
            u->actual_length = static_cast<int>(n);
            u->status = 0;
          }
        }
        if (!urb) {
          umockdev_ioctl_client_complete(client, -1, gone_ ? ENODEV : EAGAIN);
          return TRUE;
        }
        UMockdevIoctlData* ptr = umockdev_ioctl_data_resolve(arg, 0, sizeof(gpointer), nullptr);
        umockdev_ioctl_data_set_ptr(ptr, 0, urb);
        umockdev_ioctl_data_unref(ptr);
        umockdev_ioctl_data_unref(urb);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      }
      case USBDEVFS_DISCARDURB: {
        const auto address = reinterpret_cast<gulong>(*reinterpret_cast<void**>(arg->data));
        for (auto it = flying_.begin(); it != flying_.end(); ++it)
          if ((*it)->client_addr == address) {
            discarded_.push_back(*it);
            flying_.erase(it);
            umockdev_ioctl_client_complete(client, 0, 0);
            return TRUE;
          }
        umockdev_ioctl_client_complete(client, -1, EINVAL);
        return TRUE;
      }
      default:
        return FALSE;
    }
  }

  UMockdevTestbed* testbed_ = nullptr;
  UMockdevIoctlBase* handler_ = nullptr;
  std::mutex mutex_;
  std::deque<std::uint8_t> pending_;
  std::deque<UMockdevIoctlData*> flying_, discarded_;
  bool gone_ = false;
};

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
  source.start(rec.state_callback(), rec.stream_callback());
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
  source.start(rec.state_callback(), rec.stream_callback());

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

int main(int argc, char** argv) {
  // libusb must see umockdev's sysfs and /dev: run under its preload library.
  const char* old = std::getenv("LD_PRELOAD");
  if (!old || !std::strstr(old, "libumockdev-preload")) {
    std::string preload = "libumockdev-preload.so.0";
    if (old && *old) preload = std::string(old) + ":" + preload;
    ::setenv("LD_PRELOAD", preload.c_str(), 1);
    ::setenv("ASAN_OPTIONS", (std::string(std::getenv("ASAN_OPTIONS") ? std::getenv("ASAN_OPTIONS") : "") + ":verify_asan_link_order=0").c_str(), 1);
    ::execv("/proc/self/exe", argv);
    std::perror("re-executing under umockdev's preload library");
    return 1;
  }
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
