#pragma once
// Frames from a GigE Vision camera (or frame grabber) through Aravis 0.8: discovery by
// name, serial or address; pixel format, region, frame rate and packet size; a buffer
// pool; stream statistics; device timestamps mapped onto the host clock; and recovery:
// when the camera or its cable goes away the source reports it, tears down, rediscovers
// the camera and resumes on its own.
#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "evar/acquisition/frame_source.hpp"

namespace evar::acquisition {

struct GigECameraInfo {
  std::string id;        ///< Aravis device id, e.g. "Aravis-Fake-EVAR001"
  std::string address;   ///< e.g. "192.168.2.10"
  std::string serial, vendor, model;
};

/// The GigE Vision cameras answering discovery now (all interfaces, loopback included).
std::vector<GigECameraInfo> list_gige_cameras();

struct Region {
  int x = 0, y = 0, width = 0, height = 0;
};

struct GigECameraOptions {
  /// Device id, serial number or IP address; empty takes the only camera there is.
  std::string camera;
  PixelFormat pixel_format = PixelFormat::Mono16;
  std::optional<Region> region;             ///< default: the camera's current region
  std::optional<double> frame_rate_hz;      ///< default: the camera's current rate
  std::optional<int> packet_size;           ///< bytes; default: negotiated with the camera
  int buffers = 16;                         ///< the pool handed to the stream
  /// The stream socket's receive buffer holds this many frames' packets, so a stream thread
  /// that waits for the CPU loses none (the kernel caps it at net.core.rmem_max).
  int socket_buffer_frames = 8;
  /// Aravis's packet socket (less CPU per packet than a UDP socket) only when asked and the
  /// process holds CAP_NET_RAW explicitly (docs/SECURITY.md); never on loopback, where it
  /// receives nothing. Otherwise a plain UDP socket, whoever runs the node.
  bool packet_socket = false;
  std::chrono::milliseconds stall_after{500};          ///< no frame for this long → Stalled
  /// Stalled this long → ask the camera if it is there; sending frames of another pixel
  /// format or size for this long → set the camera up again.
  std::chrono::milliseconds probe_after{1500};
  std::chrono::milliseconds reconnect_interval{500};
};

struct GigEStatistics {
  SequenceStats frames;                 ///< from the GVSP block ids, across reconnections
  std::uint64_t completed = 0, failed = 0, underruns = 0;  ///< Aravis stream counters, summed
  /// Whole frames refused because the camera sent another pixel format or size than it was
  /// set to (it changed them by itself mid-stream); never delivered under the wrong label.
  std::uint64_t refused = 0;
  std::uint64_t connections = 0, outages = 0;
  double longest_outage_ms = 0.0;
  std::optional<std::int64_t> clock_offset_ns;  ///< host steady clock − device clock
  std::optional<std::int64_t> typical_delay_ns;
  std::string camera_id;                ///< the camera actually opened
  int packet_size = 0;
  int socket_buffer_bytes = 0;          ///< the receive buffer asked for, within net.core.rmem_max
  std::string socket_buffer_note;       ///< why it holds less than socket_buffer_frames (empty when it does not)
  bool packet_socket = false;           ///< Aravis's packet socket in use (see GigECameraOptions)
};

class GigECameraSource final : public FrameSource {
 public:
  explicit GigECameraSource(GigECameraOptions options);
  ~GigECameraSource() override;
  /// Starts the acquisition thread; a camera that is not there yet is reported as
  /// Connecting (with the reason) and looked for again, never thrown. Callbacks run on that
  /// thread; they may query this source but must not start or stop it.
  void start(FrameCallback on_frame, StateCallback on_state) override;
  void stop() override;
  StreamState state() const override;
  SequenceStats statistics() const override;
  std::string description() const override;
  GigEStatistics gige_statistics() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace evar::acquisition
