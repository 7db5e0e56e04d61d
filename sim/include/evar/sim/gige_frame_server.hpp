#pragma once
// Plays frames as a GigE Vision camera: Aravis's fake GV camera on a network interface
// (loopback by default), whose pixels are the latest frame handed to show(). The camera
// free-runs at the frame rate its client sets, as a frame grabber on a C-arm's video output
// does; the client is evarnode's own GigE source or any GigE Vision viewer.
#include <atomic>
#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

#include "evar/acquisition/frame.hpp"

struct _ArvGvFakeCamera;

namespace evar::sim {

struct GigEFrameServerFill;

class GigEFrameServer {
 public:
  /// Starts the camera; throws std::runtime_error when it cannot (interface missing, GVCP
  /// port 3956 taken by another camera on that interface).
  explicit GigEFrameServer(const std::string& serial, const std::string& interface = "lo");
  ~GigEFrameServer();
  GigEFrameServer(const GigEFrameServer&) = delete;
  GigEFrameServer& operator=(const GigEFrameServer&) = delete;

  /// The picture of every frame sent from now on. Mono16 frames are sent as they are
  /// (Mono8 clients get the high byte, Mono12 clients the high 12 bits); a camera region larger than the frame is padded
  /// with zeros, a smaller one shows the frame's top-left corner. Throws for other formats.
  void show(const acquisition::Frame& frame);
  /// Fault injection: each GVSP packet from now on is lost with this probability (0 to 1),
  /// as on a bad cable or an overloaded switch. The camera does not resend, so a frame that
  /// lost a packet is lost. Throws std::invalid_argument outside [0, 1].
  void set_packet_loss(double probability);
  /// Fault injection: the camera switches itself to this pixel format mid-stream, as one
  /// does after a reset, without telling its client. A client that sets it up again
  /// (writes PixelFormat) switches it back.
  void switch_pixel_format(acquisition::PixelFormat format);
  /// The id a client opens it by ("Aravis-Fake-<serial>").
  std::string device_id() const;
  std::uint64_t frames_sent() const { return sent_; }

 private:
  friend struct GigEFrameServerFill;  // the camera thread's callback (in the .cpp)
  void paint(std::uint8_t* data, int width, int height, int bits);  // bits: 8, 12 or 16 per pixel

  _ArvGvFakeCamera* camera_ = nullptr;
  std::string serial_;
  std::mutex mutex_;
  std::vector<std::uint16_t> pixels_;
  int width_ = 0, height_ = 0;
  std::atomic<std::uint64_t> sent_{0};
};

}  // namespace evar::sim
