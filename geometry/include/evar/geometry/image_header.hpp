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

/// Largest side accepted (a long, narrow image may have it) and largest pixel count in all:
/// four times the largest flat-panel detector (about 4k x 4k). A single-channel 16-bit
/// image of it is 128 MiB, a four-channel one 512 MiB. Detector sizes in node.json and
/// session.json are held to the same limits.
inline constexpr std::int64_t kMaxImageSidePx = 16384;
inline constexpr std::int64_t kMaxImagePixels = std::int64_t{8192} * 8192;

/// Reads the format and size of a PNG (IHDR), TIFF (the first IFD's ImageWidth and
/// ImageLength, either byte order) or JPEG (the first start-of-frame segment). Throws
/// InputError "<source>: ..." naming the byte offset when the header is cut short or
/// malformed, and the format when it is none of the three.
ImageHeader read_image_header(std::string_view bytes, const std::string& source);

}  // namespace evar::geometry
