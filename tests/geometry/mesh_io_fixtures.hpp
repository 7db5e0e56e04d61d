#pragma once
// What the mesh reader and writer tests share: a folder per test, the error a reader or
// validator gives, hand-made binary files, and meshes with known corner cases.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>

#include "evar/base/input_error.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/triangle_mesh.hpp"
#include "support/file_bytes.hpp"

namespace evar::test::mesh_io {

namespace fs = std::filesystem;
using evar::base::InputError;
using evar::geometry::format_for_extension;
using evar::geometry::LoadedMesh;
using evar::geometry::mean_edge_length;
using evar::geometry::MeshFormat;
using evar::geometry::read_mesh;
using evar::geometry::TriangleMesh;
using evar::geometry::validate_mesh;
using evar::geometry::write_mesh;
using evar::test::read_bytes;
using evar::test::write_bytes;
using testing::HasSubstr;

// A fresh folder per test under the GoogleTest temp dir.
inline fs::path test_dir() {
  const auto* info = testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::path(testing::TempDir()) / ("evar_geometry_io_" + std::to_string(::getpid())) /
                       (std::string(info->test_suite_name()) + "." + info->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// The message of the InputError thrown by read_mesh(path), or a test failure.
inline std::string read_error(const fs::path& path) {
  try {
    read_mesh(path);
  } catch (const evar::base::InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "read_mesh(" << path << ") did not throw evar::base::InputError";
  return {};
}

inline std::string validate_error(const TriangleMesh& mesh) {
  try {
    validate_mesh(mesh, "patient7/aorta.stl");
  } catch (const evar::base::InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "validate_mesh did not throw evar::base::InputError";
  return {};
}

// Little- and big-endian binary builders for hand-made files.
template <class T>
inline void put(std::string& out, T value, bool big_endian = false) {
  char b[sizeof(T)];
  std::memcpy(b, &value, sizeof(T));
  if (big_endian != (std::endian::native == std::endian::big)) std::reverse(b, b + sizeof(T));
  out.append(b, sizeof(T));
}

// A unit cube, outward-facing triangles.
inline TriangleMesh unit_cube() {
  TriangleMesh m;
  m.V.resize(8, 3);
  m.V << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1;
  m.F.resize(12, 3);
  m.F << 0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4, 3, 7, 6, 3, 6, 2, 0, 4, 7, 0, 7, 3,
      1, 2, 6, 1, 6, 5;
  return m;
}

// Binary STL bytes for the triangles of `mesh` (as floats), with the given header text.
inline std::string binary_stl(const TriangleMesh& mesh, const std::string& header_text) {
  std::string out = header_text;
  out.resize(80, ' ');
  put(out, static_cast<std::uint32_t>(mesh.F.rows()));
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) put(out, 0.0f);  // normal: readers must not depend on it
    for (int c = 0; c < 3; ++c) {
      for (int k = 0; k < 3; ++k) put(out, static_cast<float>(mesh.V(mesh.F(f, c), k)));
    }
    put(out, std::uint16_t{0});
  }
  return out;
}

// Same triangles (corner by corner, as coordinates), whatever the vertex numbering.
inline void expect_same_triangles(const TriangleMesh& expected, const TriangleMesh& actual) {
  ASSERT_EQ(expected.F.rows(), actual.F.rows());
  for (Eigen::Index f = 0; f < expected.F.rows(); ++f) {
    for (int c = 0; c < 3; ++c) {
      for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(expected.V(expected.F(f, c), k), actual.V(actual.F(f, c), k))
            << "face " << f << " corner " << c;
      }
    }
  }
}

// A mesh whose coordinates are not floats, with an unreferenced vertex (index 4), and
// faces that do not use vertices in order.
inline TriangleMesh irregular_mesh() {
  TriangleMesh m;
  m.V.resize(6, 3);
  m.V << 12.345678901234567, -98.76543210987654, 0.1, 1e-7, 3.0 / 7.0, -250.5, 77.7, 0.3, 1.0 / 3.0,
      -0.0, 5.5, 6.25, 999.999, -999.999, 42.0, -3.141592653589793, 2.718281828459045, 1e5;
  m.F.resize(3, 3);
  m.F << 3, 0, 5, 5, 0, 1, 2, 5, 1;
  return m;
}

inline TriangleMesh rounded_to_float(TriangleMesh m) {
  m.V = m.V.cast<float>().cast<double>();
  return m;
}

}  // namespace evar::test::mesh_io
