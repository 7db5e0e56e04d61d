#include "evar/geometry/image_file.hpp"

#include <opencv2/imgcodecs.hpp>
#include <string>

#include "evar/geometry/image_header.hpp"
#include "evar/geometry/input_error.hpp"
#include "evar/geometry/input_file.hpp"

namespace evar::geometry {

cv::Mat read_image_file(const std::filesystem::path& file, std::string_view only_format) {
  const std::string bytes = read_input_file(file, kImageLimit);
  const ImageHeader header = read_image_header(bytes, file.string());
  if (!only_format.empty() && header.format != only_format)
    throw InputError(file.string() + ": is a " + header.format + " file; only " + std::string(only_format) +
                     " is accepted here");
  cv::Mat image;
  try {
    image = cv::imdecode(cv::Mat(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<char*>(bytes.data())),
                         cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    throw InputError(file.string() + ": cannot decode the image (" + e.msg + ")");
  }
  if (image.empty()) throw InputError(file.string() + ": the " + header.format + " image cannot be decoded");
  if (image.cols != header.width || image.rows != header.height)
    throw InputError(file.string() + ": the " + header.format + " header says " + std::to_string(header.width) + " x " +
                     std::to_string(header.height) + " pixels but " + std::to_string(image.cols) + " x " +
                     std::to_string(image.rows) + " were decoded");
  return image;
}

}  // namespace evar::geometry
