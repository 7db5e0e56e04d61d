#include "v4l2_buffer_conversion.hpp"

#include <linux/videodev2.h>

#include <algorithm>
#include <cstring>
#include <opencv2/imgcodecs.hpp>

namespace evar::acquisition {

PixelFormat frame_format_of(std::uint32_t fourcc) {
  return fourcc == V4L2_PIX_FMT_Y16 ? PixelFormat::Mono16 : PixelFormat::Mono8;
}

namespace {

std::string short_buffer(const V4l2Layout& l, std::size_t need, std::size_t have) {
  return fourcc_to_string(l.fourcc) + " " + std::to_string(l.width) + "x" + std::to_string(l.height) +
         " buffer holds " + std::to_string(have) + " bytes, needs " + std::to_string(need);
}

}  // namespace

std::optional<std::string> convert_v4l2_buffer(const V4l2Layout& l, std::span<const std::uint8_t> data, Frame& out) {
  if (l.width <= 0 || l.height <= 0) return "V4L2 layout has no size";
  const auto w = static_cast<std::size_t>(l.width), h = static_cast<std::size_t>(l.height);
  out.format = frame_format_of(l.fourcc);
  out.width = l.width;
  out.height = l.height;
  out.stride_bytes = l.width * bytes_per_pixel(out.format);
  const std::size_t row_out = static_cast<std::size_t>(out.stride_bytes);

  if (l.fourcc == V4L2_PIX_FMT_MJPEG) {
    if (data.size() < 4 || data[0] != 0xFF || data[1] != 0xD8)
      return "MJPEG buffer of " + std::to_string(data.size()) + " bytes does not start with a JPEG SOI marker";
    cv::Mat decoded;
    try {
      const cv::Mat encoded(1, static_cast<int>(data.size()), CV_8UC1, const_cast<std::uint8_t*>(data.data()));
      decoded = cv::imdecode(encoded, cv::IMREAD_GRAYSCALE);
    } catch (const cv::Exception& e) {
      return std::string("MJPEG buffer does not decode: ") + e.what();
    }
    if (decoded.empty()) return "MJPEG buffer of " + std::to_string(data.size()) + " bytes does not decode";
    if (decoded.cols != l.width || decoded.rows != l.height)
      return "MJPEG frame decodes to " + std::to_string(decoded.cols) + "x" + std::to_string(decoded.rows) +
             ", the negotiated size is " + std::to_string(l.width) + "x" + std::to_string(l.height);
    out.pixels.resize(w * h);
    for (std::size_t y = 0; y < h; ++y) std::memcpy(out.pixels.data() + y * w, decoded.ptr(static_cast<int>(y)), w);
    return std::nullopt;
  }

  const std::size_t in_bpp = l.fourcc == V4L2_PIX_FMT_GREY ? 1 : 2;
  const std::size_t row_in = std::max<std::size_t>(static_cast<std::size_t>(std::max(l.bytes_per_line, 0)), w * in_bpp);
  const std::size_t need = row_in * (h - 1) + w * in_bpp;  // the last row need not be padded
  if (data.size() < need) return short_buffer(l, need, data.size());
  out.pixels.resize(row_out * h);
  switch (l.fourcc) {
    case V4L2_PIX_FMT_GREY:
    case V4L2_PIX_FMT_Y16:  // little-endian words, as Frame stores them
      for (std::size_t y = 0; y < h; ++y) std::memcpy(out.pixels.data() + y * row_out, data.data() + y * row_in, row_out);
      return std::nullopt;
    case V4L2_PIX_FMT_YUYV:  // Y0 U Y1 V: luma is every other byte
      for (std::size_t y = 0; y < h; ++y) {
        const std::uint8_t* in = data.data() + y * row_in;
        std::uint8_t* o = out.pixels.data() + y * row_out;
        for (std::size_t x = 0; x < w; ++x) o[x] = in[2 * x];
      }
      return std::nullopt;
    default:
      return "V4L2 format " + fourcc_to_string(l.fourcc) + " is not one evarnode reads (GREY, Y16, YUYV, MJPG)";
  }
}

}  // namespace evar::acquisition
