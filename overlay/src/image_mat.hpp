#pragma once
// An Image's pixels as an OpenCV matrix over the same buffer (no copy), after checking
// that the buffer holds width x height BGR pixels (internal to evar_overlay).
#include <opencv2/core.hpp>
#include <stdexcept>
#include <string>

#include "evar/overlay/mesh_preview.hpp"

namespace evar::overlay::detail {

inline cv::Mat wrap(Image& image) {
  if (image.width < 0 || image.height < 0 ||
      image.bgr.size() != static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height) * 3)
    throw std::invalid_argument("image holds " + std::to_string(image.bgr.size()) + " bytes, expected " +
                                std::to_string(image.width) + " x " + std::to_string(image.height) + " x 3");
  return {image.height, image.width, CV_8UC3, image.bgr.data()};
}

/// For readers only (display, encoding): cv::Mat has no read-only view.
inline cv::Mat wrap(const Image& image) { return wrap(const_cast<Image&>(image)); }

}  // namespace evar::overlay::detail
