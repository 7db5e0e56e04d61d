#include "evar/acquisition/usb_carm_source.hpp"

#include <libusb.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdio>
#include <stdexcept>
#include <thread>
#include <tuple>
#include <utility>

#include "carm_link_receiver.hpp"

namespace evar::acquisition {

namespace {

using Clock = std::chrono::steady_clock;
constexpr int kMaxStalls = 10;  // halts in a row, nothing read between, before the device counts as gone

std::string hex4(std::uint16_t v) {
  char b[8];
  std::snprintf(b, sizeof b, "%04x", v);
  return b;
}
std::string hex2(std::uint8_t v) {
  char b[8];
  std::snprintf(b, sizeof b, "0x%02x", v);
  return b;
}

std::string usb_error(int rc) { return std::string(libusb_error_name(rc)) + " (" + libusb_strerror(rc) + ")"; }

// RAII over libusb's handles.
struct Context {
  libusb_context* p = nullptr;
  Context() {
    if (const int rc = libusb_init(&p); rc != 0) throw std::runtime_error("libusb_init failed: " + usb_error(rc));
  }
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;
  ~Context() { libusb_exit(p); }
};

struct DeviceList {
  libusb_device** list = nullptr;
  ssize_t count = 0;
  explicit DeviceList(libusb_context* ctx) {
    count = libusb_get_device_list(ctx, &list);
    if (count < 0) throw std::runtime_error("libusb_get_device_list failed: " + usb_error(static_cast<int>(count)));
  }
  DeviceList(const DeviceList&) = delete;
  DeviceList& operator=(const DeviceList&) = delete;
  ~DeviceList() {
    if (list) libusb_free_device_list(list, 1);
  }
};

struct ConfigDescriptor {
  libusb_config_descriptor* p = nullptr;
  ConfigDescriptor() = default;
  ConfigDescriptor(const ConfigDescriptor&) = delete;
  ConfigDescriptor& operator=(const ConfigDescriptor&) = delete;
  ~ConfigDescriptor() {
    if (p) libusb_free_config_descriptor(p);
  }
};

// An open device with (after claim) its interface claimed; released and closed in reverse.
struct DeviceHandle {
  libusb_device_handle* p = nullptr;
  int claimed = -1;
  DeviceHandle() = default;
  DeviceHandle(const DeviceHandle&) = delete;
  DeviceHandle& operator=(const DeviceHandle&) = delete;
  ~DeviceHandle() { reset(); }
  void reset() {
    if (p && claimed >= 0) libusb_release_interface(p, claimed);
    if (p) libusb_close(p);
    p = nullptr;
    claimed = -1;
  }
};

UsbTransferType transfer_type(std::uint8_t attributes) {
  switch (attributes & LIBUSB_TRANSFER_TYPE_MASK) {
    case LIBUSB_TRANSFER_TYPE_BULK: return UsbTransferType::Bulk;
    case LIBUSB_TRANSFER_TYPE_INTERRUPT: return UsbTransferType::Interrupt;
    default: return UsbTransferType::Other;
  }
}

std::vector<UsbInterface> interfaces_of(libusb_device* dev) {
  ConfigDescriptor config;
  if (libusb_get_active_config_descriptor(dev, &config.p) != 0 &&
      libusb_get_config_descriptor(dev, 0, &config.p) != 0)
    return {};
  std::vector<UsbInterface> out;
  for (int i = 0; i < config.p->bNumInterfaces; ++i) {
    const libusb_interface& itf = config.p->interface[i];
    for (int a = 0; a < itf.num_altsetting; ++a) {
      const libusb_interface_descriptor& d = itf.altsetting[a];
      UsbInterface u{d.bInterfaceNumber, d.bAlternateSetting, {}};
      for (int e = 0; e < d.bNumEndpoints; ++e)
        u.endpoints.push_back({d.endpoint[e].bEndpointAddress, transfer_type(d.endpoint[e].bmAttributes),
                               d.endpoint[e].wMaxPacketSize});
      out.push_back(std::move(u));
    }
  }
  return out;
}

std::string read_string(libusb_device_handle* h, std::uint8_t index) {
  if (index == 0) return {};
  std::array<unsigned char, 256> buf{};
  const int n = libusb_get_string_descriptor_ascii(h, index, buf.data(), static_cast<int>(buf.size()));
  return n > 0 ? std::string(reinterpret_cast<const char*>(buf.data()), static_cast<std::size_t>(n)) : std::string();
}

std::string describe_endpoints(const std::vector<UsbInterface>& interfaces) {
  std::string s;
  for (const auto& i : interfaces) {
    s += (s.empty() ? "" : "; ") + ("interface " + std::to_string(i.number)) +
         (i.alternate ? "." + std::to_string(i.alternate) : "") + ":";
    if (i.endpoints.empty()) s += " no endpoints";
    for (const auto& e : i.endpoints)
      s += " " + hex2(e.address) + ((e.address & 0x80) ? " IN " : " OUT ") +
           (e.type == UsbTransferType::Bulk ? "bulk" : e.type == UsbTransferType::Interrupt ? "interrupt" : "other");
  }
  return s.empty() ? "no interfaces" : s;
}

}  // namespace

UsbDeviceId parse_usb_device_id(const std::string& text) {
  auto hex_id = [&](const std::string& part, const char* what) {
    if (part.empty() || part.size() > 4 ||
        !std::all_of(part.begin(), part.end(), [](char c) { return std::isxdigit(static_cast<unsigned char>(c)); }))
      throw std::invalid_argument("USB device '" + text + "': " + what + " '" + part +
                                  "' is not a 4-digit hexadecimal id (as lsusb prints it, e.g. 1209:ea01)");
    return static_cast<std::uint16_t>(std::stoul(part, nullptr, 16));
  };
  const auto first = text.find(':');
  if (first == std::string::npos) throw std::invalid_argument("USB device '" + text + "': expected VID:PID[:SERIAL]");
  const auto second = text.find(':', first + 1);
  UsbDeviceId id;
  id.vendor = hex_id(text.substr(0, first), "vendor id");
  id.product = hex_id(text.substr(first + 1, second == std::string::npos ? std::string::npos : second - first - 1),
                      "product id");
  if (second != std::string::npos) {
    id.serial = text.substr(second + 1);
    if (id.serial.empty()) throw std::invalid_argument("USB device '" + text + "': empty serial number after the second ':'");
  }
  return id;
}

std::string to_string(const UsbDeviceId& id) {
  return hex4(id.vendor) + ":" + hex4(id.product) + (id.serial.empty() ? "" : ":" + id.serial);
}

UsbEndpointChoice choose_usb_endpoint(const std::vector<UsbInterface>& interfaces, std::optional<int> interface_number,
                                      std::optional<std::uint8_t> endpoint_address) {
  if (endpoint_address && !(*endpoint_address & 0x80))
    throw std::runtime_error("endpoint " + hex2(*endpoint_address) + " is an OUT endpoint; the C-arm link reads an IN endpoint (0x81..0x8f)");
  for (const auto& itf : interfaces) {
    if (interface_number && itf.number != *interface_number) continue;
    for (const auto& e : itf.endpoints) {
      const bool readable = (e.address & 0x80) && e.type != UsbTransferType::Other;
      if (endpoint_address ? e.address == *endpoint_address && readable : readable)
        return {itf.number, itf.alternate, e};
    }
  }
  std::string want = endpoint_address ? "IN endpoint " + hex2(*endpoint_address) : std::string("a bulk or interrupt IN endpoint");
  if (interface_number) want += " on interface " + std::to_string(*interface_number);
  throw std::runtime_error("the device has no " + want + " (it has " + describe_endpoints(interfaces) + ")");
}

struct UsbCArmSource::Impl {
  UsbLinkOptions options;
  CArmLinkReceiver receiver;
  std::unique_ptr<Context> context;
  libusb_hotplug_callback_handle hotplug_handle = 0;
  bool has_hotplug = false;
  std::atomic<bool> stop{false};
  std::atomic<bool> arrived{false};
  std::thread thread;

  explicit Impl(UsbLinkOptions o)
      : options(std::move(o)), receiver("USB " + to_string(options.device), options.stale_after) {}

  static int on_hotplug(libusb_context*, libusb_device*, libusb_hotplug_event event, void* self) {
    if (event == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED) static_cast<Impl*>(self)->arrived = true;
    return 0;  // stay registered
  }

  // Runs libusb's events (hotplug) for up to `d`; true when stop was asked.
  bool wait(std::chrono::milliseconds d) {
    const auto until = Clock::now() + d;
    while (!stop && !arrived && Clock::now() < until) {
      timeval tv{0, 50'000};
      libusb_handle_events_timeout_completed(context->p, &tv, nullptr);
    }
    return stop;
  }

  // Finds, opens and claims the device; returns the endpoint to read.
  UsbEndpointChoice open(DeviceHandle& handle) {
    const UsbDeviceId& want = options.device;
    DeviceList devices(context->p);
    std::string seen;
    for (ssize_t i = 0; i < devices.count; ++i) {
      libusb_device* dev = devices.list[i];
      libusb_device_descriptor desc{};
      if (libusb_get_device_descriptor(dev, &desc) != 0) continue;
      if (desc.idVendor != want.vendor || desc.idProduct != want.product) continue;
      DeviceHandle h;
      if (const int rc = libusb_open(dev, &h.p); rc != 0) {
        seen += (seen.empty() ? "" : "; ") + std::string("one cannot be opened: ") + usb_error(rc) +
                (rc == LIBUSB_ERROR_ACCESS ? " (add a udev rule giving this user access)" : "");
        continue;
      }
      if (!want.serial.empty()) {
        const std::string serial = read_string(h.p, desc.iSerialNumber);
        if (serial != want.serial) {
          seen += (seen.empty() ? "" : "; ") + std::string("one has serial '") + serial + "'";
          continue;
        }
      }
      UsbEndpointChoice choice;
      try {
        choice = choose_usb_endpoint(interfaces_of(dev), options.interface_number, options.endpoint);
      } catch (const std::runtime_error& e) {  // another device with these ids may fit
        seen += (seen.empty() ? "" : "; ") + std::string("one does not fit: ") + e.what();
        continue;
      }
      libusb_set_auto_detach_kernel_driver(h.p, 1);  // e.g. cdc_acm bound to a serial adapter
      if (const int rc = libusb_claim_interface(h.p, choice.interface_number); rc != 0)
        throw std::runtime_error("cannot claim interface " + std::to_string(choice.interface_number) + ": " + usb_error(rc));
      h.claimed = choice.interface_number;
      if (choice.alternate != 0)
        if (const int rc = libusb_set_interface_alt_setting(h.p, choice.interface_number, choice.alternate); rc != 0)
          throw std::runtime_error("cannot select alternate setting " + std::to_string(choice.alternate) + ": " + usb_error(rc));
      std::swap(handle.p, h.p);
      std::swap(handle.claimed, h.claimed);
      return choice;
    }
    throw std::runtime_error("no USB device " + to_string(want) + (seen.empty() ? std::string(" is connected") : " (" + seen + ")"));
  }

  // Reads until the device goes away or stop; returns why it went away.
  std::string read(DeviceHandle& handle, const UsbEndpointChoice& choice) {
    // Whole packets, so a transfer never ends inside one (a partial packet would overflow).
    const int packet = std::max<int>(choice.endpoint.max_packet, 8);
    std::vector<unsigned char> buffer(static_cast<std::size_t>(packet * std::max(1, 4096 / packet)));
    const auto timeout = static_cast<unsigned>(options.transfer_timeout.count());
    int stalls = 0;  // in a row, nothing read between them
    while (!stop) {
      int got = 0;
      const int rc = choice.endpoint.type == UsbTransferType::Interrupt
                         ? libusb_interrupt_transfer(handle.p, choice.endpoint.address, buffer.data(),
                                                     static_cast<int>(buffer.size()), &got, timeout)
                         : libusb_bulk_transfer(handle.p, choice.endpoint.address, buffer.data(),
                                                static_cast<int>(buffer.size()), &got, timeout);
      const auto now = Clock::now();
      if (got > 0) {
        receiver.received({buffer.data(), static_cast<std::size_t>(got)}, now);
        stalls = 0;
      }
      switch (rc) {
        case 0:
        case LIBUSB_ERROR_TIMEOUT:
        case LIBUSB_ERROR_INTERRUPTED:
        case LIBUSB_ERROR_OVERFLOW:  // bytes lost; the decoder counts the torn frame and resyncs
          break;
        case LIBUSB_ERROR_PIPE:  // the endpoint halted: clear it and go on
          if (const int c = libusb_clear_halt(handle.p, choice.endpoint.address); c != 0)
            return "endpoint " + hex2(choice.endpoint.address) + " stalled and cannot be cleared: " + usb_error(c);
          // One that stalls at once every time would spin this thread: back off (20 to
          // 320 ms), and after kMaxStalls in a row treat the device as gone (reopened).
          if (++stalls >= kMaxStalls)
            return "endpoint " + hex2(choice.endpoint.address) + " stalled " + std::to_string(stalls) + " times in a row";
          std::this_thread::sleep_for(std::chrono::milliseconds(10 << std::min(stalls, 5)));
          break;
        default:
          return usb_error(rc);
      }
      receiver.tick(now);
    }
    return {};
  }

  void run() {
    const std::string name = "USB " + to_string(options.device);
    while (!stop) {
      arrived = false;
      DeviceHandle handle;
      UsbEndpointChoice choice;
      try {
        choice = open(handle);
      } catch (const std::exception& e) {
        handle.reset();
        receiver.connecting(std::string(e.what()) + (has_hotplug ? "; waiting for it to be plugged in" : "; looking again every " +
                                                        std::to_string(options.reconnect_interval.count()) + " ms"));
        if (wait(options.reconnect_interval)) break;
        continue;
      }
      receiver.connected();
      const std::string lost = read(handle, choice);
      handle.reset();
      if (stop) break;
      receiver.disconnected(name + " endpoint " + hex2(choice.endpoint.address) + ": " + lost + "; reconnecting");
      if (wait(options.reconnect_interval)) break;
    }
    receiver.stopped();
  }
};

UsbCArmSource::UsbCArmSource(UsbLinkOptions options) {
  if (options.transfer_timeout <= std::chrono::milliseconds(0) || options.transfer_timeout > std::chrono::seconds(1))
    throw std::invalid_argument("USB C-arm link: transfer timeout must be 1..1000 ms");
  if (options.endpoint && !(*options.endpoint & 0x80))
    throw std::invalid_argument("USB C-arm link: endpoint " + hex2(*options.endpoint) + " is not an IN endpoint");
  impl_ = std::make_unique<Impl>(std::move(options));
}

UsbCArmSource::~UsbCArmSource() { stop(); }

void UsbCArmSource::start(StateCallback on_state, StreamCallback on_stream, NoticeCallback on_notice) {
  if (impl_->thread.joinable()) throw std::logic_error("USB C-arm link: already started");
  if (!impl_->context) {
    impl_->context = std::make_unique<Context>();
    impl_->has_hotplug = libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG) != 0 &&
                         libusb_hotplug_register_callback(
                             impl_->context->p, LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED, LIBUSB_HOTPLUG_NO_FLAGS,
                             impl_->options.device.vendor, impl_->options.device.product, LIBUSB_HOTPLUG_MATCH_ANY,
                             &Impl::on_hotplug, impl_.get(), &impl_->hotplug_handle) == LIBUSB_SUCCESS;
  }
  impl_->receiver.set_callbacks(std::move(on_state), std::move(on_stream), std::move(on_notice));
  impl_->stop = false;
  impl_->thread = std::thread([this] { impl_->run(); });
}

void UsbCArmSource::stop() {
  if (!impl_->thread.joinable()) return;
  impl_->stop = true;
  libusb_interrupt_event_handler(impl_->context->p);
  impl_->thread.join();  // the thread reported Stopped as its last word
}

StreamState UsbCArmSource::state() const { return impl_->receiver.state(); }

std::string UsbCArmSource::description() const {
  const auto& o = impl_->options;
  return "C-arm link on USB " + to_string(o.device) + (o.endpoint ? " endpoint " + hex2(*o.endpoint) : "");
}

CArmLinkStatistics UsbCArmSource::statistics() const { return impl_->receiver.statistics(); }


std::vector<UsbDeviceInfo> list_usb_devices(const std::optional<UsbDeviceId>& filter) {
  Context context;
  DeviceList devices(context.p);
  std::vector<UsbDeviceInfo> out;
  for (ssize_t i = 0; i < devices.count; ++i) {
    libusb_device* dev = devices.list[i];
    libusb_device_descriptor desc{};
    if (libusb_get_device_descriptor(dev, &desc) != 0) continue;
    if (filter && (desc.idVendor != filter->vendor || desc.idProduct != filter->product)) continue;
    UsbDeviceInfo info;
    info.id.vendor = desc.idVendor;
    info.id.product = desc.idProduct;
    info.bus = libusb_get_bus_number(dev);
    info.address = libusb_get_device_address(dev);
    info.interfaces = interfaces_of(dev);
    DeviceHandle h;
    if (const int rc = libusb_open(dev, &h.p); rc == 0) {
      info.manufacturer = read_string(h.p, desc.iManufacturer);
      info.product = read_string(h.p, desc.iProduct);
      info.id.serial = read_string(h.p, desc.iSerialNumber);
    } else {
      info.error = "cannot open: " + usb_error(rc);
    }
    if (filter && !filter->serial.empty() && info.id.serial != filter->serial) continue;
    out.push_back(std::move(info));
  }
  std::sort(out.begin(), out.end(), [](const UsbDeviceInfo& a, const UsbDeviceInfo& b) {
    return std::tie(a.bus, a.address) < std::tie(b.bus, b.address);
  });
  return out;
}

}  // namespace evar::acquisition
