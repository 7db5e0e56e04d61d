// View geometry JSON (a C-arm pose) and the CT to C-arm registration JSON.
#include "evar/geometry/carm_projection.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = evar::fuzz::write_file("view.json", {data, size});
  evar::fuzz::expect_clean_rejection(path, [&] { (void)evar::geometry::read_view_geometry(path); });
  evar::fuzz::expect_clean_rejection(path, [&] { (void)evar::geometry::read_registration(path); });
  return 0;
}
