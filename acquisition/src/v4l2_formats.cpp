#include "evar/acquisition/v4l2_formats.hpp"

#include <linux/videodev2.h>

#include <algorithm>
#include <cctype>
#include <cstring>

namespace evar::acquisition {

std::string fourcc_list(const std::vector<std::uint32_t>& fourccs) {
  std::string s;
  for (auto c : fourccs) s += (s.empty() ? "" : ", ") + fourcc_to_string(c);
  return s.empty() ? "none" : s;
}

std::string fourcc_to_string(std::uint32_t fourcc) {
  std::string s(4, ' ');
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((fourcc >> (8 * i)) & 0xFF);
    s[static_cast<std::size_t>(i)] = std::isprint(static_cast<unsigned char>(c)) ? c : '?';
  }
  return s;
}

std::optional<std::uint32_t> fourcc_from_string(std::string_view name) {
  std::string n(name);
  for (char& c : n) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (n == "GREY" || n == "GRAY") return V4L2_PIX_FMT_GREY;
  if (n == "Y16") return V4L2_PIX_FMT_Y16;
  if (n == "YUYV") return V4L2_PIX_FMT_YUYV;
  if (n == "MJPG" || n == "MJPEG") return V4L2_PIX_FMT_MJPEG;
  return std::nullopt;
}

const std::vector<std::uint32_t>& readable_v4l2_formats() {
  static const std::vector<std::uint32_t> formats{V4L2_PIX_FMT_Y16, V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_YUYV,
                                                  V4L2_PIX_FMT_MJPEG};
  return formats;
}

bool is_readable_v4l2_format(std::uint32_t fourcc) {
  const auto& f = readable_v4l2_formats();
  return std::find(f.begin(), f.end(), fourcc) != f.end();
}

}  // namespace evar::acquisition
