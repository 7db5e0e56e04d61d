#pragma once
// The hardware sources named on a command line or in a node configuration: a GigE Vision
// camera or a V4L2 grabber, and the C-arm link over serial or USB.
#include <memory>
#include <optional>
#include <string>

#include "evar/acquisition/carm_geometry_source.hpp"
#include "evar/acquisition/frame_source.hpp"

namespace evar::app {

struct FrameSourceSpec {
  std::string camera;                 ///< GigE camera id, serial or address ("" = the only one)
  std::string pixel_format = "mono16";
  std::string v4l2;                   ///< /dev/videoN instead of a GigE camera
  std::string v4l2_format;            ///< Y16, GREY, YUYV or MJPG ("" = the deepest offered)
  std::optional<int> width, height;
  std::optional<double> fps;
  bool packet_socket = false;         ///< GigE: Aravis's packet socket, if CAP_NET_RAW is granted
};

/// std::invalid_argument naming the option for a spec that cannot be right.
std::unique_ptr<acquisition::FrameSource> make_frame_source(const FrameSourceSpec& spec);

/// serial:PATH[,baud=N][,parity=none|even|odd][,stop=1|2] or usb:VID:PID[:SERIAL];
/// std::invalid_argument naming the part that is wrong.
std::unique_ptr<acquisition::CArmGeometrySource> make_carm_source(const std::string& spec);

}  // namespace evar::app
