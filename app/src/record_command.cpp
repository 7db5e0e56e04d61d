// `evarnode record`: a live session from the frame grabber and the C-arm link, written in
// the session format (docs/SESSION_FORMAT.md) with live statistics on the terminal.
#include <unistd.h>

#include <cstdio>
#include <memory>
#include <thread>

#include "commands.hpp"
#include "evar/acquisition/gige_camera_source.hpp"
#include "evar/acquisition/serial_carm_source.hpp"
#include "evar/acquisition/usb_carm_source.hpp"
#include "evar/acquisition/v4l2_frame_source.hpp"
#include "evar/geometry/carm_projection.hpp"
#include "evar/sim/session_recorder.hpp"
#include "interrupt.hpp"
#include "logging.hpp"

namespace evar::app {
namespace {

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
    if (o.settings.stop_bits != 1 && o.settings.stop_bits != 2)
      throw std::invalid_argument("--carm " + spec + ": stop bits must be 1 or 2");
    return std::make_unique<acquisition::SerialCArmSource>(o);
  }
  throw std::invalid_argument("--carm '" + spec + "': expected serial:/dev/ttyUSB0[,baud=115200] or usb:VID:PID[:SERIAL]");
}

std::unique_ptr<acquisition::FrameSource> make_frame_source(const RecordCommand& cmd) {
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
  return std::make_unique<acquisition::GigECameraSource>(o);
}

}  // namespace

int run_record(const RecordCommand& cmd) {
  auto frames = make_frame_source(cmd);
  auto carm = make_carm_source(cmd.carm);
  sim::RecorderOptions o;
  o.out = cmd.out;
  o.scene = cmd.scene;
  o.ct_to_carm = geometry::read_registration(cmd.registration);
  o.pixel_spacing_mm = cmd.pixel_spacing_mm;
  o.device_thickness_mm = cmd.device_thickness_mm;
  sim::SessionRecorder recorder(o, *frames, *carm);
  log().info("recording {} and {} into {}", frames->description(), carm->description(), cmd.out.string());
  log().info("stop with Ctrl-C{}{}", cmd.seconds ? fmt::format(", or after {:g} s", *cmd.seconds) : "",
             cmd.frames ? fmt::format(", or after {} frames", *cmd.frames) : "");

  const InterruptGuard ctrl_c;
  recorder.start();
  const bool terminal = ::isatty(STDERR_FILENO) == 1;
  auto last_print = std::chrono::steady_clock::now();
  std::uint64_t last_frames = 0;
  sim::RecorderStatistics s, shown;
  for (;;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    s = recorder.statistics();
    // State changes are news: a stalled grabber or a silent C-arm is said at once.
    if (s.video != shown.video || s.video_reason != shown.video_reason)
      (acquisition::is_live(s.video) ? log().info("video: {}", s.video_reason) : log().warn("video: {}", s.video_reason));
    if (s.carm != shown.carm || s.carm_reason != shown.carm_reason)
      (acquisition::is_live(s.carm) ? log().info("C-arm: {}", s.carm_reason) : log().warn("C-arm: {}", s.carm_reason));
    shown = s;
    const auto now = std::chrono::steady_clock::now();
    const double since = std::chrono::duration<double>(now - last_print).count();
    if (since >= (terminal ? 1.0 : 10.0)) {
      const auto fs = frames->statistics();
      std::fprintf(stderr, "%s%7.1f s  frames %llu written %llu (dropped %llu, not recorded %llu)  %5.1f fps  |  C-arm %llu samples%s",
                   terminal ? "\r" : "", s.seconds, static_cast<unsigned long long>(s.frames_received),
                   static_cast<unsigned long long>(s.frames_written), static_cast<unsigned long long>(fs.dropped),
                   static_cast<unsigned long long>(s.frames_not_recorded + s.frames_refused),
                   static_cast<double>(s.frames_received - last_frames) / since,
                   static_cast<unsigned long long>(s.carm_samples), terminal ? "   " : "\n");
      last_print = now;
      last_frames = s.frames_received;
    }
    if (ctrl_c.interrupted() || (cmd.seconds && s.seconds >= *cmd.seconds) ||
        (cmd.frames && s.frames_written >= static_cast<std::uint64_t>(*cmd.frames)))
      break;
  }
  if (terminal) std::fprintf(stderr, "\n");
  const sim::Session session = recorder.finish();
  s = recorder.statistics();
  log().info("{}: {} frames and {} C-arm states in {:.1f} s; {} frames dropped by the source, {} not recorded",
             cmd.out.string(), session.frames.size(), session.carm.size(), s.seconds, frames->statistics().dropped,
             s.frames_not_recorded + s.frames_refused);
  if (!s.last_error.empty()) log().warn("last problem: {}", s.last_error);
  log().info("report: {}", (cmd.out / "record_report.json").string());
  return 0;
}

}  // namespace evar::app
