#pragma once
// The C-arm geometry over USB through libusb: the same C-arm link frames as the serial
// line, read from a bulk or interrupt IN endpoint of the C-arm's (or its adapter's) USB
// device, chosen by vendor and product id and optionally serial number. Reconnects on its
// own when the device is unplugged and comes back, at once where the platform reports
// hotplug events, else by looking again every reconnect interval.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "evar/acquisition/carm_geometry_source.hpp"
#include "evar/acquisition/carm_link_statistics.hpp"

namespace evar::acquisition {

struct UsbDeviceId {
  std::uint16_t vendor = 0, product = 0;
  std::string serial;  ///< empty: any
};

/// Parses "VID:PID" or "VID:PID:SERIAL" (hexadecimal ids, as lsusb prints them). Throws
/// std::invalid_argument naming what is wrong.
UsbDeviceId parse_usb_device_id(const std::string& text);
std::string to_string(const UsbDeviceId& id);

enum class UsbTransferType { Bulk, Interrupt, Other };

/// One endpoint as the configuration descriptor lists it.
struct UsbEndpoint {
  std::uint8_t address = 0;  ///< bit 7 set: IN
  UsbTransferType type = UsbTransferType::Other;
  std::uint16_t max_packet = 0;
};
struct UsbInterface {
  int number = 0, alternate = 0;
  std::vector<UsbEndpoint> endpoints;
};

struct UsbEndpointChoice {
  int interface_number = 0, alternate = 0;
  UsbEndpoint endpoint;
};

/// The endpoint the link reads: the one asked for, or else the first bulk or interrupt IN
/// endpoint (of the interface asked for, or of any). Throws std::runtime_error saying what
/// the device offers when nothing fits.
UsbEndpointChoice choose_usb_endpoint(const std::vector<UsbInterface>& interfaces, std::optional<int> interface_number,
                                      std::optional<std::uint8_t> endpoint_address);

struct UsbLinkOptions {
  UsbDeviceId device;
  std::optional<int> interface_number;      ///< default: the first with a bulk/interrupt IN endpoint
  std::optional<std::uint8_t> endpoint;     ///< IN endpoint address, e.g. 0x81
  std::chrono::milliseconds reconnect_interval{250};
  std::chrono::milliseconds stale_after{1000};   ///< no geometry for this long → Stalled
  std::chrono::milliseconds transfer_timeout{50};  ///< one read; also the stall resolution
};

class UsbCArmSource final : public CArmGeometrySource {
 public:
  explicit UsbCArmSource(UsbLinkOptions options);
  ~UsbCArmSource() override;
  /// Starts the link thread. Throws only when libusb cannot start at all; a missing device
  /// is reported as Connecting with the reason and looked for again.
  void start(StateCallback on_state, StreamCallback on_stream, NoticeCallback on_notice) override;
  void stop() override;
  StreamState state() const override;
  std::string description() const override;
  CArmLinkStatistics statistics() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct UsbDeviceInfo {
  UsbDeviceId id;            ///< serial filled where it could be read
  int bus = 0, address = 0;
  std::string manufacturer, product;
  std::vector<UsbInterface> interfaces;
  std::string error;         ///< why the strings could not be read (often: no permission)
};

/// The USB devices on the system, those matching `filter` only when it is given (serial
/// ignored when empty). Throws std::runtime_error when libusb cannot start.
std::vector<UsbDeviceInfo> list_usb_devices(const std::optional<UsbDeviceId>& filter = std::nullopt);

}  // namespace evar::acquisition
