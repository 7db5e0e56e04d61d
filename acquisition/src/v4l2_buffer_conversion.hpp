#pragma once
// How one filled V4L2 buffer becomes a Frame, in the format v4l2_formats.hpp names.
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "evar/acquisition/frame.hpp"
#include "evar/acquisition/v4l2_formats.hpp"

namespace evar::acquisition {

/// The Frame format a V4L2 format is delivered as.
PixelFormat frame_format_of(std::uint32_t fourcc);

/// Fills `out` (format, size, stride, pixels) from one dequeued buffer holding `data`
/// (its bytesused). Returns a message naming what is wrong for a buffer that is short or
/// does not decode; `out` is then unspecified.
std::optional<std::string> convert_v4l2_buffer(const V4l2Layout& layout, std::span<const std::uint8_t> data,
                                               Frame& out);

}  // namespace evar::acquisition
