// DICOM XA / Enhanced XA: geometry attributes and pixel data.
#include "evar/geometry/xa_dicom.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = evar::fuzz::write_file("input.dcm", {data, size});
  evar::fuzz::expect_clean_rejection(path, [&] { (void)evar::geometry::read_xa_dicom(path, 0); });
  return 0;
}
