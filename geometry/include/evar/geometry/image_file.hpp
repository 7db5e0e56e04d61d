#pragma once
// Image files (PNG, TIFF, JPEG, ... as OpenCV reads them) decoded from one read of the file:
// the size limit holds and no other file can be swapped in between the checks and the read.
#include <filesystem>
#include <opencv2/core.hpp>
#include <string_view>

namespace evar::geometry {

/// Depth and channels as stored (IMREAD_UNCHANGED). InputError naming the file when it is
/// missing, too large (kImageLimit), not PNG, TIFF or JPEG, declares more pixels than
/// image_header.hpp allows (checked before decoding) or cannot be decoded. With
/// `only_format` ("PNG", "TIFF" or "JPEG", as read_image_header names them), any other
/// format is refused by its signature, whatever the file is named.
cv::Mat read_image_file(const std::filesystem::path& file, std::string_view only_format = {});

}  // namespace evar::geometry
