#pragma once
// A test pattern in a V4L2 buffer's layout, and how many pixels of a delivered frame miss it.
#include <linux/videodev2.h>

#include <cstdint>
#include <vector>

#include "evar/acquisition/frame.hpp"

namespace evar::test {

// A sensor image that differs in every pixel and frame, in the device's negotiated layout.
inline std::uint16_t expected_value(int x, int y, int seed, acquisition::PixelFormat f) {
  const int v = x * 7 + y * 13 + seed * 101;
  return static_cast<std::uint16_t>(f == acquisition::PixelFormat::Mono16 ? (v * 37) & 0xFFFF : v & 0xFF);
}

inline std::vector<std::uint8_t> payload_for(const v4l2_pix_format& fmt, int seed) {
  const int w = static_cast<int>(fmt.width), h = static_cast<int>(fmt.height);
  std::vector<std::uint8_t> p(fmt.sizeimage, 0xEE);  // padding bytes are never read
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      std::uint8_t* row = p.data() + static_cast<std::size_t>(y) * fmt.bytesperline;
      switch (fmt.pixelformat) {
        case V4L2_PIX_FMT_GREY: row[x] = static_cast<std::uint8_t>(expected_value(x, y, seed, acquisition::PixelFormat::Mono8)); break;
        case V4L2_PIX_FMT_Y16: {
          const std::uint16_t v = expected_value(x, y, seed, acquisition::PixelFormat::Mono16);
          row[2 * x] = static_cast<std::uint8_t>(v & 0xFF);
          row[2 * x + 1] = static_cast<std::uint8_t>(v >> 8);
          break;
        }
        case V4L2_PIX_FMT_YUYV:
          row[2 * x] = static_cast<std::uint8_t>(expected_value(x, y, seed, acquisition::PixelFormat::Mono8));
          row[2 * x + 1] = static_cast<std::uint8_t>(x % 2 ? 90 : 160);  // chroma, ignored
          break;
      }
    }
  return p;
}

inline int mismatches(const acquisition::Frame& f, int seed) {
  int bad = 0;
  for (int y = 0; y < f.height; ++y)
    for (int x = 0; x < f.width; ++x) {
      const std::uint8_t* row = f.pixels.data() + static_cast<std::size_t>(y) * f.stride_bytes;
      const int v = f.format == acquisition::PixelFormat::Mono16 ? row[2 * x] | (row[2 * x + 1] << 8) : row[x];
      bad += v != expected_value(x, y, seed, f.format);
    }
  return bad;
}

}  // namespace evar::test
