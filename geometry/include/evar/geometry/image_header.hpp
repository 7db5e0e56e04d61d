#pragma once
// The size an image file declares, read from its header before anything is decoded: a
// small compressed file can declare gigapixels, and the decoder would allocate them.
#include <cstdint>
#include <string>
#include <string_view>

namespace evar::geometry {

struct ImageHeader {
  std::string format;  ///< "PNG", "TIFF" or "JPEG"
  std::int64_t width = 0, height = 0;  ///< pixels
};

/// Largest side accepted (the largest detector node.json describes) and largest pixel
/// count (a single-channel 16-bit image of it is 512 MiB; four channels, 2 GiB).
inline constexpr std::int64_t kMaxImageSidePx = 16384;
inline constexpr std::int64_t kMaxImagePixels = kMaxImageSidePx * kMaxImageSidePx;

/// Reads the format and size of a PNG (IHDR), TIFF (the first IFD's ImageWidth and
/// ImageLength, either byte order) or JPEG (the first start-of-frame segment). Throws
/// InputError "<source>: ..." naming the byte offset when the header is cut short or
/// malformed, and the format when it is none of the three.
ImageHeader read_image_header(std::string_view bytes, const std::string& source);

}  // namespace evar::geometry
