#pragma once
// A grabbed video frame with the three clocks of PLUS-style streams: the device's own
// timestamp, the host arrival time and the device sequence number.
#include <chrono>
#include <cstdint>
#include <vector>

namespace evar::acquisition {

enum class PixelFormat { Mono8, Mono12, Mono16 };

/// Bytes per pixel as stored in Frame::pixels (Mono12 is stored in 16-bit words).
int bytes_per_pixel(PixelFormat format);
const char* to_string(PixelFormat format);

struct Frame {
  PixelFormat format = PixelFormat::Mono8;
  int width = 0, height = 0;
  int stride_bytes = 0;                    ///< bytes per row in `pixels`
  std::vector<std::uint8_t> pixels;        ///< row-major, little-endian words for 12/16 bit
  std::uint64_t sequence = 0;              ///< device sequence number
  std::int64_t device_time_ns = 0;         ///< device clock (arbitrary epoch)
  std::chrono::steady_clock::time_point host_arrival;  ///< when the host received it
  /// The device timestamp mapped onto the host's steady clock by the source's clock-offset
  /// estimate (equal to host_arrival where the source has no device clock).
  std::chrono::steady_clock::time_point device_time_on_host;
  /// device_time_ns is the device's own clock, mapped by an online estimate that sees only
  /// earlier frames; a recording may map it again from (device_time_ns, host_arrival) with
  /// every frame (acquisition::device_times_on_host). False where device_time_on_host is
  /// already exact or is the arrival time.
  bool device_clock = false;
};

/// Throws std::invalid_argument naming the size, stride or byte count when `pixels` cannot
/// hold the frame its fields declare: what reads its rows must check this first.
void check_layout(const Frame& frame);

}  // namespace evar::acquisition
