#include "source_factory.hpp"

#include <stdexcept>

#include "evar/acquisition/gige_camera_source.hpp"
#include "evar/acquisition/process_capabilities.hpp"
#include "evar/acquisition/serial_carm_source.hpp"
#include "evar/acquisition/usb_carm_source.hpp"
#include "evar/acquisition/v4l2_frame_source.hpp"
#include "evar/node/logging.hpp"

namespace evar::app {


std::unique_ptr<acquisition::CArmGeometrySource> make_carm_source(const std::string& spec) {
  if (spec.starts_with("usb:")) {
    acquisition::UsbLinkOptions o;
    o.device = acquisition::parse_usb_device_id(spec.substr(4));
    return std::make_unique<acquisition::UsbCArmSource>(o);
  }
  if (spec.starts_with("serial:")) {
    // serial:PATH[,baud=N][,parity=none|even|odd][,stop=1|2]
    acquisition::SerialLinkOptions o;
    std::string rest = spec.substr(7);
    std::size_t comma = rest.find(',');
    o.path = rest.substr(0, comma);
    while (comma != std::string::npos) {
      const std::size_t next = rest.find(',', comma + 1);
      const std::string item = rest.substr(comma + 1, next == std::string::npos ? std::string::npos : next - comma - 1);
      const std::size_t eq = item.find('=');
      const std::string key = item.substr(0, eq), value = eq == std::string::npos ? "" : item.substr(eq + 1);
      try {
        if (key == "baud") o.settings.baud = std::stoi(value);
        else if (key == "parity") o.settings.parity = acquisition::parse_parity(value);
        else if (key == "stop") o.settings.stop_bits = std::stoi(value);
        else throw std::invalid_argument("unknown setting");
      } catch (const std::exception&) {
        throw std::invalid_argument("--carm " + spec + ": '" + item +
                                    "' is not baud=N, parity=none|even|odd or stop=1|2");
      }
      comma = next;
    }
    return std::make_unique<acquisition::SerialCArmSource>(o);
  }
  throw std::invalid_argument("--carm '" + spec + "': expected serial:/dev/ttyUSB0[,baud=115200] or usb:VID:PID[:SERIAL]");
}

std::unique_ptr<acquisition::FrameSource> make_frame_source(const FrameSourceSpec& cmd) {
  if (!cmd.v4l2.empty()) {
    acquisition::V4l2Options o;
    o.device = cmd.v4l2;
    if (!cmd.v4l2_format.empty()) {
      const auto f = acquisition::fourcc_from_string(cmd.v4l2_format);
      if (!f) throw std::invalid_argument("--v4l2-format " + cmd.v4l2_format + ": expected Y16, GREY, YUYV or MJPG");
      o.formats = {*f};
    }
    o.width = cmd.width;
    o.height = cmd.height;
    o.frame_rate_hz = cmd.fps;
    return std::make_unique<acquisition::V4l2FrameSource>(o);
  }
  acquisition::GigECameraOptions o;
  o.camera = cmd.camera;
  o.pixel_format = cmd.pixel_format == "mono8"    ? acquisition::PixelFormat::Mono8
                   : cmd.pixel_format == "mono12" ? acquisition::PixelFormat::Mono12
                                                  : acquisition::PixelFormat::Mono16;
  if (cmd.width.has_value() != cmd.height.has_value())
    throw std::invalid_argument("a GigE camera region needs --width and --height together");
  if (cmd.width) o.region = acquisition::Region{0, 0, *cmd.width, *cmd.height};
  o.frame_rate_hz = cmd.fps;
  o.packet_socket = cmd.packet_socket;
  if (cmd.packet_socket)
    node::log().info(acquisition::has_effective_capability(acquisition::kCapNetRaw)
                   ? "GigE packet socket requested; CAP_NET_RAW is held, so Aravis uses it (not on loopback)"
                   : "GigE packet socket requested, but CAP_NET_RAW is not granted: plain UDP sockets are used");
  return std::make_unique<acquisition::GigECameraSource>(o);
}


}  // namespace evar::app
