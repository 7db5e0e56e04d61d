#include "evar/acquisition/frame.hpp"

#include <stdexcept>
#include <string>

namespace evar::acquisition {

int bytes_per_pixel(PixelFormat format) { return format == PixelFormat::Mono8 ? 1 : 2; }

const char* to_string(PixelFormat format) {
  switch (format) {
    case PixelFormat::Mono8: return "Mono8";
    case PixelFormat::Mono12: return "Mono12";
    case PixelFormat::Mono16: return "Mono16";
  }
  return "unknown";
}

void check_layout(const Frame& f) {
  if (f.width <= 0 || f.height <= 0)
    throw std::invalid_argument("frame size " + std::to_string(f.width) + " x " + std::to_string(f.height));
  const auto row = static_cast<std::size_t>(f.width) * static_cast<std::size_t>(bytes_per_pixel(f.format));
  if (f.stride_bytes < 0 || static_cast<std::size_t>(f.stride_bytes) < row)
    throw std::invalid_argument("frame stride " + std::to_string(f.stride_bytes) + " bytes is shorter than a row of " +
                                std::to_string(f.width) + " " + to_string(f.format) + " pixels");
  // The last row needs only its pixels, not a whole stride (a grabber's last line may end early).
  const std::size_t need = static_cast<std::size_t>(f.stride_bytes) * static_cast<std::size_t>(f.height - 1) + row;
  if (f.pixels.size() < need)
    throw std::invalid_argument("frame of " + std::to_string(f.width) + " x " + std::to_string(f.height) + " " +
                                to_string(f.format) + " holds " + std::to_string(f.pixels.size()) + " bytes, not " +
                                std::to_string(need));
}

}  // namespace evar::acquisition
