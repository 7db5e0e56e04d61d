#include "evar/geometry/image_file.hpp"

#include <cstdint>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "evar/geometry/image_header.hpp"
#include "evar/base/input_error.hpp"
#include "evar/base/input_file.hpp"

namespace evar::geometry {

cv::Mat read_image_file(const std::filesystem::path& file, std::string_view only_format) {
  const std::string bytes = base::read_input_file(file, base::kImageLimit);
  const ImageHeader header = read_image_header(bytes, file.string());
  if (!only_format.empty() && header.format != only_format)
    throw base::InputError(file.string() + ": is a " + header.format + " file; only " + std::string(only_format) +
                     " is accepted here");
  cv::Mat image;
  try {
    image = cv::imdecode(cv::Mat(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<char*>(bytes.data())),
                         cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    throw base::InputError(file.string() + ": cannot decode the image (" + e.msg + ")");
  }
  if (image.empty()) throw base::InputError(file.string() + ": the " + header.format + " image cannot be decoded");
  if (image.cols != header.width || image.rows != header.height)
    throw base::InputError(file.string() + ": the " + header.format + " header says " + std::to_string(header.width) + " x " +
                     std::to_string(header.height) + " pixels but " + std::to_string(image.cols) + " x " +
                     std::to_string(image.rows) + " were decoded");
  return image;
}

void write_image_file(const std::filesystem::path& file, const cv::Mat& image, const ImageEncoding& encoding) {
  const std::string format = encoding.format.empty() ? file.extension().string() : encoding.format;
  if (format.empty() || !cv::haveImageWriter(format))
    throw std::runtime_error(file.string() + ": cannot write a picture named so (name it .png, .tif or .jpg)");
  std::vector<std::uint8_t> bytes;
  try {
    if (!cv::imencode(format, image, bytes, encoding.params))
      throw std::runtime_error(file.string() + ": the picture cannot be encoded as " + format);
  } catch (const cv::Exception& e) {
    throw std::runtime_error(file.string() + ": the picture cannot be encoded as " + format + " (" + e.msg + ")");
  }
  base::write_file_atomically(file, {reinterpret_cast<const char*>(bytes.data()), bytes.size()}, encoding.durability);
}

}  // namespace evar::geometry
