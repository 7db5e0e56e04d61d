#pragma once
// Image files (PNG, TIFF, JPEG, ... as OpenCV reads them) decoded from one read of the file:
// the size limit holds and no other file can be swapped in between the checks and the read.
// Written, they appear whole or not at all (base/atomic_file.hpp).
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "evar/base/atomic_file.hpp"

namespace evar::geometry {

/// Depth and channels as stored (IMREAD_UNCHANGED). InputError naming the file when it is
/// missing, too large (kImageLimit), not PNG, TIFF or JPEG, declares more pixels than
/// image_header.hpp allows (checked before decoding) or cannot be decoded. With
/// `only_format` ("PNG", "TIFF" or "JPEG", as read_image_header names them), any other
/// format is refused by its signature, whatever the file is named.
cv::Mat read_image_file(const std::filesystem::path& file, std::string_view only_format = {});

struct ImageEncoding {
  std::string format;       ///< ".png", ".tif", ".jpg"; empty: from the file's extension
  std::vector<int> params;  ///< as cv::imwrite takes them (cv::IMWRITE_PNG_COMPRESSION, 1, ...)
  base::Durability durability = base::Durability::Synced;
};

/// Encodes `image` and writes it through an AtomicFile. std::runtime_error naming the file
/// when the format is not one OpenCV encodes (saying which names work) or the image cannot
/// be encoded in it; std::system_error naming it when it cannot be written.
void write_image_file(const std::filesystem::path& file, const cv::Mat& image, const ImageEncoding& encoding = {});

}  // namespace evar::geometry
