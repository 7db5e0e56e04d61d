// 3D Slicer markups JSON (centerlines, the device, landmarks).
#include "evar/geometry/markups.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = evar::fuzz::write_file("input.mrk.json", {data, size});
  evar::fuzz::expect_clean_rejection(path, [&] { (void)evar::geometry::read_markups(path); });
  evar::fuzz::expect_clean_rejection(path, [&] { (void)evar::geometry::read_curve(path); });
  evar::fuzz::expect_clean_rejection(path, [&] { (void)evar::geometry::read_fiducials(path); });
  return 0;
}
