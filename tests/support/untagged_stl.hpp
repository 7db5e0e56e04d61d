#pragma once
// A binary STL as segmentation tools write one: coordinates in whatever frame they are, and
// no SPACE tag in its header (evarnode's own writer always declares one).
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "evar/geometry/triangle_mesh.hpp"

namespace evar::test {

inline void write_untagged_stl(const std::filesystem::path& path, const geometry::TriangleMesh& m) {
  std::ofstream out(path, std::ios::binary);
  const std::string header(80, ' ');
  out.write(header.data(), 80);
  const auto n = static_cast<std::uint32_t>(m.F.rows());
  out.write(reinterpret_cast<const char*>(&n), 4);
  for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
    float values[12] = {};  // the facet normal (left zero, as readers recompute it), then the corners
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a) values[3 + 3 * k + a] = static_cast<float>(m.V(m.F(f, k), a));
    out.write(reinterpret_cast<const char*>(values), sizeof values);
    const std::uint16_t attributes = 0;
    out.write(reinterpret_cast<const char*>(&attributes), 2);
  }
}

}  // namespace evar::test
