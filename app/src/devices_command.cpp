// `evarnode devices`: what acquisition hardware this machine can see, so a clinical
// engineer can pick the names for `evarnode record` and `evarnode run`.
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "evar/acquisition/gige_camera_source.hpp"
#include "evar/acquisition/serial_ports.hpp"
#include "evar/acquisition/usb_carm_source.hpp"
#include "evar/acquisition/v4l2_frame_source.hpp"
#include "logging.hpp"

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

std::string formats_text(const std::vector<std::uint32_t>& formats) {
  std::string s;
  for (auto f : formats) s += (s.empty() ? "" : ", ") + acquisition::fourcc_to_string(f);
  return s.empty() ? "none" : s;
}

}  // namespace

int run_devices(const DevicesCommand& cmd) {
  ordered_json report = {{"format", "evarnode-devices"}, {"version", 1}};
  std::string errors;  // parts that could not be asked; the rest is still shown

  ordered_json gige = ordered_json::array();
  for (const auto& c : acquisition::list_gige_cameras())
    gige.push_back({{"id", c.id}, {"address", c.address}, {"serial", c.serial}, {"vendor", c.vendor}, {"model", c.model}});
  report["gige_cameras"] = gige;

  const auto v4l2_devices = acquisition::list_v4l2_devices();
  ordered_json v4l2 = ordered_json::array();
  for (const auto& d : v4l2_devices) {
    ordered_json formats = ordered_json::array();
    for (auto f : d.formats) formats.push_back(acquisition::fourcc_to_string(f));
    v4l2.push_back({{"path", d.path}, {"driver", d.driver}, {"card", d.card}, {"bus_info", d.bus_info},
                    {"capture", d.can_capture}, {"formats", formats}, {"error", d.error}});
  }
  report["v4l2_devices"] = v4l2;

  ordered_json serial = ordered_json::array();
  for (const auto& p : acquisition::list_serial_ports())
    serial.push_back({{"path", p.path}, {"kind", p.kind}, {"by_id", p.by_id}});
  report["serial_ports"] = serial;

  ordered_json usb = ordered_json::array();
  std::optional<acquisition::UsbDeviceId> filter;
  if (!cmd.usb.empty()) filter = acquisition::parse_usb_device_id(cmd.usb);
  try {
    for (const auto& d : acquisition::list_usb_devices(filter)) {
      usb.push_back({{"id", acquisition::to_string(d.id)}, {"bus", d.bus}, {"address", d.address},
                     {"manufacturer", d.manufacturer}, {"product", d.product}, {"endpoints", endpoints_text(d.interfaces)},
                     {"error", d.error}});
    }
  } catch (const std::exception& e) {
    errors += std::string("USB: ") + e.what();
  }
  report["usb_devices"] = usb;
  report["errors"] = errors;

  if (cmd.json) {
    std::cout << report.dump(2) << "\n";
    return 0;
  }
  auto heading = [](const char* h) { std::cout << h << "\n"; };
  heading("GigE Vision cameras (discovery on every interface, loopback included):");
  if (gige.empty()) std::cout << "  none answered\n";
  for (const auto& c : gige)
    std::cout << "  " << c["id"].get<std::string>() << "  at " << c["address"].get<std::string>() << "  serial "
              << c["serial"].get<std::string>() << "  (" << c["vendor"].get<std::string>() << " "
              << c["model"].get<std::string>() << ")   --camera " << c["serial"].get<std::string>() << "\n";
  heading("V4L2 video devices (/dev/video*):");
  if (v4l2.empty()) std::cout << "  none (no /dev/video* on this machine)\n";
  for (const auto& d : v4l2_devices) {
    std::cout << "  " << d.path;
    if (!d.error.empty()) {
      std::cout << "  " << d.error << "\n";
      continue;
    }
    std::cout << "  " << d.card << " (" << d.driver << ", " << d.bus_info << ")  "
              << (d.can_capture ? "capture, formats " + formats_text(d.formats) : std::string("not a capture node"))
              << "\n";
  }
  heading("Serial ports:");
  if (serial.empty()) std::cout << "  none\n";
  for (const auto& p : serial) {
    std::cout << "  " << p["path"].get<std::string>() << "  " << p["kind"].get<std::string>();
    for (const auto& l : p["by_id"]) std::cout << "  " << l.get<std::string>();
    std::cout << "\n";
  }
  heading(filter ? ("USB devices matching " + cmd.usb + ":").c_str() : "USB devices (--usb VID:PID to show one):");
  if (usb.empty()) std::cout << "  none\n";
  for (const auto& d : usb) {
    std::cout << "  " << d["id"].get<std::string>() << "  bus " << d["bus"] << " address " << d["address"];
    if (!d["product"].get<std::string>().empty())
      std::cout << "  " << d["manufacturer"].get<std::string>() << " " << d["product"].get<std::string>();
    std::cout << "  " << d["endpoints"].get<std::string>();
    if (!d["error"].get<std::string>().empty()) std::cout << "  (" << d["error"].get<std::string>() << ")";
    std::cout << "\n";
  }
  if (!errors.empty()) log().warn("{}", errors);
  return 0;
}

}  // namespace evar::app
