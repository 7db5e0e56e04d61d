#pragma once
// Frames from a V4L2 capture device (a USB or PCIe frame grabber on the C-arm's video
// out): format negotiation with read-back, mmap streaming, non-blocking dequeue under
// poll with a watchdog, drops from sequence-number gaps, monotonic buffer timestamps, and
// a full teardown and reopen when the device goes away (ENODEV, POLLERR) or hangs.
// Everything goes through a V4l2Io (acquisition/src/v4l2_io.hpp, the seam tests drive with
// a scripted device), so the same code runs on the kernel and where no /dev/video* exists.
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "evar/acquisition/frame_source.hpp"
#include "evar/acquisition/v4l2_formats.hpp"

namespace evar::acquisition {

class V4l2Io;

struct V4l2Options {
  std::string device = "/dev/video0";
  /// Formats to ask for, most preferred first; the first one the device offers is taken.
  /// Default: readable_v4l2_formats() (Y16, GREY, YUYV, MJPG).
  std::vector<std::uint32_t> formats;
  std::optional<int> width, height;       ///< default: the device's current size
  std::optional<double> frame_rate_hz;    ///< default: the device's current rate
  int buffers = 4;
  std::chrono::milliseconds stall_after{500};     ///< no frame for this long → Stalled
  std::chrono::milliseconds restart_after{3000};  ///< stalled this long → tear down and reopen
  std::chrono::milliseconds reconnect_interval{500};
};

struct V4l2Statistics {
  SequenceStats frames;            ///< from the driver's sequence numbers, across reopenings
  std::uint64_t bad_buffers = 0;   ///< flagged as errors by the driver, short, or not decodable
  std::uint64_t connections = 0, outages = 0, restarts = 0;
  std::string driver, card, bus_info;
  V4l2Layout layout;               ///< what the driver agreed to
  std::optional<double> frame_rate_hz;  ///< what the driver agreed to, where it says
  bool monotonic_timestamps = false;    ///< buffer times are on CLOCK_MONOTONIC (the host clock)
  std::string last_error;               ///< the last bad buffer or failed call, named
};

class V4l2FrameSource final : public FrameSource {
 public:
  /// On the kernel's devices.
  explicit V4l2FrameSource(V4l2Options options);
  /// On the calls of `io`, which must outlive the source.
  V4l2FrameSource(V4l2Options options, V4l2Io& io);
  ~V4l2FrameSource() override;
  /// Starts the capture thread. A device that is missing or refuses is reported as
  /// Connecting with the reason and tried again; only bad options throw. Callbacks run on
  /// that thread; they may query this source but must not start or stop it.
  void start(FrameCallback on_frame, StateCallback on_state) override;
  void stop() override;
  StreamState state() const override;
  SequenceStats statistics() const override;
  std::string description() const override;
  V4l2Statistics v4l2_statistics() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct V4l2DeviceInfo {
  std::string path;                    ///< /dev/video0
  std::string driver, card, bus_info;
  bool can_capture = false;            ///< video capture with streaming I/O
  std::vector<std::uint32_t> formats;  ///< as enumerated (VIDIOC_ENUM_FMT)
  std::string error;                   ///< why it could not be asked, when it could not
};

/// Every video<N> node under /dev, in number order, with what it says about itself.
std::vector<V4l2DeviceInfo> list_v4l2_devices();
/// The same under `dev_dir`, asked through `io`.
std::vector<V4l2DeviceInfo> list_v4l2_devices(V4l2Io& io, const std::filesystem::path& dev_dir);

}  // namespace evar::acquisition
