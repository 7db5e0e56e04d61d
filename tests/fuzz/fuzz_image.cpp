// Image files (PNG, TIFF, JPEG frames and fluoroscopy inputs): the header check, then
// OpenCV's decoder on whatever passes it.
#include "evar/geometry/image_file.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = evar::fuzz::write_file("frame.img", {data, size});
  evar::fuzz::expect_clean_rejection(path, [&] { (void)evar::geometry::read_image_file(path); });
  return 0;
}
