#include "evar/geometry/image_header.hpp"

#include "evar/base/input_error.hpp"

namespace evar::geometry {
namespace {

class Bytes {
 public:
  Bytes(std::string_view data, const std::string& source, std::string format)
      : data_(data), source_(source), format_(std::move(format)) {}

  std::uint32_t u8(std::size_t at) const { return byte(at); }
  std::uint32_t u16(std::size_t at, bool big_endian) const {
    return big_endian ? (byte(at) << 8) | byte(at + 1) : byte(at) | (byte(at + 1) << 8);
  }
  std::uint32_t u32(std::size_t at, bool big_endian) const {
    return big_endian ? (u16(at, true) << 16) | u16(at + 2, true) : u16(at, false) | (u16(at + 2, false) << 16);
  }
  [[noreturn]] void fail(std::size_t at, const std::string& what) const {
    throw base::InputError(source_ + ": " + format_ + " header, byte " + std::to_string(at) + ": " + what);
  }

 private:
  std::uint32_t byte(std::size_t at) const {
    if (at >= data_.size()) fail(at, "the file ends inside the header");
    return static_cast<unsigned char>(data_[at]);
  }
  std::string_view data_;
  const std::string& source_;
  std::string format_;
};

ImageHeader png(const Bytes& b) {
  // Signature (8), then the first chunk: length (4), "IHDR", width, height (big-endian).
  if (b.u32(12, true) != 0x49484452u) b.fail(12, "the first chunk is not IHDR");
  return {"PNG", b.u32(16, true), b.u32(20, true)};
}

ImageHeader tiff(const Bytes& b, bool big_endian) {
  const std::size_t ifd = b.u32(4, big_endian);
  if (ifd < 8) b.fail(4, "the first IFD offset " + std::to_string(ifd) + " points into the header");
  const std::uint32_t entries = b.u16(ifd, big_endian);
  std::int64_t width = -1, height = -1;
  for (std::uint32_t e = 0; e < entries; ++e) {
    const std::size_t at = ifd + 2 + 12 * static_cast<std::size_t>(e);
    const std::uint32_t tag = b.u16(at, big_endian);
    if (tag != 256 && tag != 257) continue;  // ImageWidth, ImageLength
    const std::uint32_t type = b.u16(at + 2, big_endian);
    std::int64_t value = 0;
    if (type == 3) value = b.u16(at + 8, big_endian);       // SHORT, left-justified in the field
    else if (type == 4) value = b.u32(at + 8, big_endian);  // LONG
    else b.fail(at + 2, "tag " + std::to_string(tag) + " has type " + std::to_string(type) + ", not SHORT or LONG");
    (tag == 256 ? width : height) = value;
  }
  if (width < 0 || height < 0) b.fail(ifd, "the first IFD has no ImageWidth or no ImageLength");
  return {"TIFF", width, height};
}

ImageHeader jpeg(const Bytes& b) {
  std::size_t at = 2;  // after SOI
  for (;;) {
    if (b.u8(at) != 0xFF) b.fail(at, "expected a marker");
    std::uint32_t marker = b.u8(at + 1);
    while (marker == 0xFF) marker = b.u8(++at + 1);  // fill bytes
    if (marker == 0xD8 || marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) {  // no length
      at += 2;
      continue;
    }
    if (marker == 0xD9 || marker == 0xDA) b.fail(at, "no start-of-frame segment before the image data");
    const bool start_of_frame = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
    if (start_of_frame) return {"JPEG", b.u16(at + 7, true), b.u16(at + 5, true)};  // precision, height, width
    const std::uint32_t length = b.u16(at + 2, true);
    if (length < 2) b.fail(at + 2, "segment length " + std::to_string(length) + " is less than 2");
    at += 2 + length;
  }
}

}  // namespace

ImageHeader read_image_header(std::string_view bytes, const std::string& source) {
  const auto starts = [&](std::string_view magic) { return bytes.substr(0, magic.size()) == magic; };
  ImageHeader h;
  if (starts("\x89PNG\r\n\x1a\n")) h = png(Bytes(bytes, source, "PNG"));
  else if (starts(std::string_view("II*\0", 4))) h = tiff(Bytes(bytes, source, "TIFF"), false);
  else if (starts(std::string_view("MM\0*", 4))) h = tiff(Bytes(bytes, source, "TIFF"), true);
  else if (starts("\xFF\xD8")) h = jpeg(Bytes(bytes, source, "JPEG"));
  else if (starts(std::string_view("II+\0", 4)) || starts(std::string_view("MM\0+", 4)))
    throw base::InputError(source + ": a BigTIFF file; only classic TIFF, PNG and JPEG images are read");
  else
    throw base::InputError(source + ": not a PNG, TIFF or JPEG image (those are the image formats read)");
  if (h.width < 1 || h.height < 1)
    throw base::InputError(source + ": the " + h.format + " header declares " + std::to_string(h.width) + " x " +
                     std::to_string(h.height) + " pixels");
  if (h.width > kMaxImageSidePx || h.height > kMaxImageSidePx || h.width * h.height > kMaxImagePixels)
    throw base::InputError(source + ": the " + h.format + " header declares " + std::to_string(h.width) + " x " +
                     std::to_string(h.height) + " pixels; at most " + std::to_string(kMaxImageSidePx) +
                     " per side and " + std::to_string(kMaxImagePixels) + " in all are read");
  return h;
}

}  // namespace evar::geometry
