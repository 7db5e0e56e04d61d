#pragma once
// The V4L2 pixel formats the grabber reads, by name, and the layout a driver agreed to:
// GREY → Mono8, Y16 (little-endian) → Mono16, YUYV → Mono8 (its luma), MJPEG → Mono8
// (decoded). Fluoroscopy is grey; colour grabbers deliver it as luma.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace evar::acquisition {

/// "GREY", "Y16 ", "YUYV", "MJPG" (the four characters of a V4L2 fourcc).
std::string fourcc_to_string(std::uint32_t fourcc);
/// "GREY, YUYV" ("none" when empty), for messages and listings.
std::string fourcc_list(const std::vector<std::uint32_t>& fourccs);
/// Accepts GREY, Y16, YUYV, MJPG or MJPEG (any case); nullopt for anything else.
std::optional<std::uint32_t> fourcc_from_string(std::string_view name);
/// The formats the grabber reads, most preferred first (deepest grey first).
const std::vector<std::uint32_t>& readable_v4l2_formats();
bool is_readable_v4l2_format(std::uint32_t fourcc);
/// What the driver agreed to (read back after VIDIOC_S_FMT).
struct V4l2Layout {
  std::uint32_t fourcc = 0;
  int width = 0, height = 0;
  int bytes_per_line = 0;      ///< 0 for compressed formats
  std::uint32_t size_image = 0;
};

}  // namespace evar::acquisition
