// `evarnode devices`: what acquisition hardware this machine can see, so a clinical
// engineer can pick the names for `evarnode record` and `evarnode run`.
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "evar/acquisition/gige_camera_source.hpp"
#include "evar/acquisition/serial_ports.hpp"
#include "evar/acquisition/usb_carm_source.hpp"
#include "evar/acquisition/v4l2_frame_source.hpp"
#include "evar/node/logging.hpp"

namespace evar::app {
namespace {

using nlohmann::ordered_json;

std::string endpoints_text(const std::vector<acquisition::UsbInterface>& interfaces) {
  std::string s;
  for (const auto& i : interfaces)
    for (const auto& e : i.endpoints) {
      if (!(e.address & 0x80) || e.type == acquisition::UsbTransferType::Other) continue;
      char b[48];
      std::snprintf(b, sizeof b, "%s0x%02x %s (interface %d)", s.empty() ? "" : ", ", e.address,
                    e.type == acquisition::UsbTransferType::Bulk ? "bulk" : "interrupt", i.number);
      s += b;
    }
  return s.empty() ? "no bulk or interrupt IN endpoint" : "IN " + s;
}

ordered_json to_json(const std::vector<acquisition::GigECameraInfo>& gige,
                     const std::vector<acquisition::V4l2DeviceInfo>& v4l2,
                     const std::vector<acquisition::SerialPortInfo>& serial,
                     const std::vector<acquisition::UsbDeviceInfo>& usb, const std::string& errors) {
  ordered_json j = {{"format", "evarnode-devices"}, {"version", 1}};
  j["gige_cameras"] = ordered_json::array();
  for (const auto& c : gige)
    j["gige_cameras"].push_back({{"id", c.id}, {"address", c.address}, {"serial", c.serial}, {"vendor", c.vendor}, {"model", c.model}});
  j["v4l2_devices"] = ordered_json::array();
  for (const auto& d : v4l2) {
    ordered_json formats = ordered_json::array();
    for (auto f : d.formats) formats.push_back(acquisition::fourcc_to_string(f));
    j["v4l2_devices"].push_back({{"path", d.path}, {"driver", d.driver}, {"card", d.card}, {"bus_info", d.bus_info},
                                 {"capture", d.can_capture}, {"formats", formats}, {"error", d.error}});
  }
  j["serial_ports"] = ordered_json::array();
  for (const auto& p : serial) j["serial_ports"].push_back({{"path", p.path}, {"kind", p.kind}, {"by_id", p.by_id}});
  j["usb_devices"] = ordered_json::array();
  for (const auto& d : usb)
    j["usb_devices"].push_back({{"id", acquisition::to_string(d.id)}, {"bus", d.bus}, {"address", d.address},
                                {"manufacturer", d.manufacturer}, {"product", d.product},
                                {"endpoints", endpoints_text(d.interfaces)}, {"error", d.error}});
  j["errors"] = errors;
  return j;
}

}  // namespace

int run_devices(const DevicesCommand& cmd) {
  std::optional<acquisition::UsbDeviceId> filter;
  if (!cmd.usb.empty()) filter = acquisition::parse_usb_device_id(cmd.usb);
  const auto gige = acquisition::list_gige_cameras();
  const auto v4l2 = acquisition::list_v4l2_devices();
  const auto serial = acquisition::list_serial_ports();
  std::vector<acquisition::UsbDeviceInfo> usb;
  std::string errors;  // parts that could not be asked; the rest is still shown
  try {
    usb = acquisition::list_usb_devices(filter);
  } catch (const std::exception& e) {
    errors = std::string("USB: ") + e.what();
  }
  if (cmd.json) {
    std::cout << to_json(gige, v4l2, serial, usb, errors).dump(2) << "\n";
    return 0;
  }

  std::cout << "GigE Vision cameras (discovery on every interface, loopback included):\n";
  if (gige.empty()) std::cout << "  none answered\n";
  for (const auto& c : gige)
    std::cout << "  " << c.id << "  at " << c.address << "  serial " << c.serial << "  (" << c.vendor << " " << c.model
              << ")   --camera " << c.serial << "\n";
  std::cout << "V4L2 video devices (/dev/video*):\n";
  if (v4l2.empty()) std::cout << "  none (no /dev/video* on this machine)\n";
  for (const auto& d : v4l2) {
    std::cout << "  " << d.path << "  ";
    if (!d.error.empty())
      std::cout << d.error << "\n";
    else
      std::cout << d.card << " (" << d.driver << ", " << d.bus_info << ")  "
                << (d.can_capture ? "capture, formats " + acquisition::fourcc_list(d.formats) : std::string("not a capture node"))
                << "\n";
  }
  std::cout << "Serial ports:\n";
  if (serial.empty()) std::cout << "  none\n";
  for (const auto& p : serial) {
    std::cout << "  " << p.path << "  " << p.kind;
    for (const auto& l : p.by_id) std::cout << "  " << l;
    std::cout << "\n";
  }
  std::cout << (filter ? "USB devices matching " + cmd.usb + ":" : std::string("USB devices (--usb VID:PID to show one):"))
            << "\n";
  if (usb.empty()) std::cout << "  none\n";
  for (const auto& d : usb) {
    std::cout << "  " << acquisition::to_string(d.id) << "  bus " << d.bus << " address " << d.address;
    if (!d.product.empty()) std::cout << "  " << d.manufacturer << " " << d.product;
    std::cout << "  " << endpoints_text(d.interfaces);
    if (!d.error.empty()) std::cout << "  (" << d.error << ")";
    std::cout << "\n";
  }
  if (!errors.empty()) node::log().warn("{}", errors);
  return 0;
}

}  // namespace evar::app
