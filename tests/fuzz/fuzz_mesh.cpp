// Mesh readers (STL binary and ASCII, PLY, OBJ, VTK legacy): the first byte picks the extension.
#include "evar/geometry/mesh_io.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const char* const kNames[] = {"input.stl", "input.ply", "input.obj", "input.vtk"};
  const auto path = evar::fuzz::write_file(kNames[data[0] % 4], {data + 1, size - 1});
  evar::fuzz::expect_clean_rejection(path, [&] { (void)evar::geometry::read_mesh(path); });
  return 0;
}
