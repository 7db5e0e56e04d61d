// Mesh reading/writing (STL, PLY, OBJ) and mesh validation: round trips, format
// detection, and every kind of malformed input ending in an InputError that names the file.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "evar/base/input_error.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/triangle_mesh.hpp"
#include "support/file_bytes.hpp"

namespace fs = std::filesystem;
using evar::geometry::format_for_extension;
using evar::base::InputError;
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

namespace {

// A fresh folder per test under the GoogleTest temp dir.
fs::path test_dir() {
  const auto* info = testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::path(testing::TempDir()) / ("evar_geometry_io_" + std::to_string(::getpid())) /
                       (std::string(info->test_suite_name()) + "." + info->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// The message of the InputError thrown by read_mesh(path), or a test failure.
std::string read_error(const fs::path& path) {
  try {
    read_mesh(path);
  } catch (const evar::base::InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "read_mesh(" << path << ") did not throw evar::base::InputError";
  return {};
}

std::string validate_error(const TriangleMesh& mesh) {
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
void put(std::string& out, T value, bool big_endian = false) {
  char b[sizeof(T)];
  std::memcpy(b, &value, sizeof(T));
  if (big_endian != (std::endian::native == std::endian::big)) std::reverse(b, b + sizeof(T));
  out.append(b, sizeof(T));
}

// A unit cube, outward-facing triangles.
TriangleMesh unit_cube() {
  TriangleMesh m;
  m.V.resize(8, 3);
  m.V << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1;
  m.F.resize(12, 3);
  m.F << 0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4, 3, 7, 6, 3, 6, 2, 0, 4, 7, 0, 7, 3,
      1, 2, 6, 1, 6, 5;
  return m;
}

// Binary STL bytes for the triangles of `mesh` (as floats), with the given header text.
std::string binary_stl(const TriangleMesh& mesh, const std::string& header_text) {
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
void expect_same_triangles(const TriangleMesh& expected, const TriangleMesh& actual) {
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
TriangleMesh irregular_mesh() {
  TriangleMesh m;
  m.V.resize(6, 3);
  m.V << 12.345678901234567, -98.76543210987654, 0.1, 1e-7, 3.0 / 7.0, -250.5, 77.7, 0.3, 1.0 / 3.0,
      -0.0, 5.5, 6.25, 999.999, -999.999, 42.0, -3.141592653589793, 2.718281828459045, 1e5;
  m.F.resize(3, 3);
  m.F << 3, 0, 5, 5, 0, 1, 2, 5, 1;
  return m;
}

TriangleMesh rounded_to_float(TriangleMesh m) {
  m.V = m.V.cast<float>().cast<double>();
  return m;
}

}  // namespace

// ---- STL ---------------------------------------------------------------------------

TEST(StlRead, BinaryCubeIsWeldedInto8VerticesAnd12ManifoldFaces) {
  const fs::path file = test_dir() / "cube.stl";
  write_bytes(file, binary_stl(unit_cube(), "cube exported by a CAD tool"));

  const LoadedMesh loaded = read_mesh(file);
  EXPECT_EQ(loaded.format, MeshFormat::StlBinary);
  EXPECT_EQ(loaded.mesh.V.rows(), 8);
  EXPECT_EQ(loaded.mesh.F.rows(), 12);
  EXPECT_NO_THROW(validate_mesh(loaded.mesh, file.string()));
  expect_same_triangles(unit_cube(), loaded.mesh);
  // Vertices are numbered in order of first appearance: the first triangle's corners.
  EXPECT_EQ(loaded.mesh.F(0, 0), 0);
  EXPECT_EQ(loaded.mesh.F(0, 1), 1);
  EXPECT_EQ(loaded.mesh.F(0, 2), 2);
}

TEST(StlRead, BinaryFileWhoseHeaderStartsWithSolidIsReadAsBinary) {
  const fs::path file = test_dir() / "solid_header.stl";
  write_bytes(file, binary_stl(unit_cube(), "solid cube; many exporters write this in binary files"));

  const LoadedMesh loaded = read_mesh(file);
  EXPECT_EQ(loaded.format, MeshFormat::StlBinary);
  EXPECT_EQ(loaded.mesh.V.rows(), 8);
  EXPECT_EQ(loaded.mesh.F.rows(), 12);
}

TEST(StlRead, AsciiIsDetectedAndWeldedWithCrlfAndMixedCaseKeywords) {
  const fs::path file = test_dir() / "two.STL";
  write_bytes(file,
              "solid two triangles\r\n"
              "  facet normal 0 0 1\r\n    outer loop\r\n"
              "      vertex 0 0 0\r\n      vertex 1 0 0\r\n      vertex 0 1 0\r\n"
              "    endloop\r\n  endfacet\r\n"
              "  FACET NORMAL 0 0 1\r\n    OUTER LOOP\r\n"
              "      VERTEX 1 0 0\r\n      VERTEX +1.0 1e0 0\r\n      VERTEX 0 1 0\r\n"
              "    ENDLOOP\r\n  ENDFACET\r\n"
              "endsolid two triangles\r\n");
  const LoadedMesh loaded = read_mesh(file);
  EXPECT_EQ(loaded.format, MeshFormat::StlAscii);
  ASSERT_EQ(loaded.mesh.V.rows(), 4);
  ASSERT_EQ(loaded.mesh.F.rows(), 2);
  EXPECT_EQ(loaded.mesh.F.row(0), Eigen::RowVector3i(0, 1, 2));
  EXPECT_EQ(loaded.mesh.F.row(1), Eigen::RowVector3i(1, 3, 2));
  EXPECT_EQ(loaded.mesh.V.row(3), Eigen::RowVector3d(1, 1, 0));
}

TEST(StlRead, AsciiWithSeveralSolidsIsReadWhole) {
  const fs::path file = test_dir() / "parts.stl";
  write_bytes(file,
              "solid a\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
              "endloop\nendfacet\nendsolid a\n"
              "solid b\nfacet normal 0 0 0\nouter loop\nvertex 5 0 0\nvertex 6 0 0\nvertex 5 1 0\n"
              "endloop\nendfacet\nendsolid b\n");
  const LoadedMesh loaded = read_mesh(file);
  EXPECT_EQ(loaded.mesh.F.rows(), 2);
  EXPECT_EQ(loaded.mesh.V.rows(), 6);
}

class StlRoundTrip : public testing::TestWithParam<MeshFormat> {};

TEST_P(StlRoundTrip, KeepsTrianglesExactlyAtFloatPrecision) {
  const fs::path file = test_dir() / "mesh.stl";
  const TriangleMesh original = irregular_mesh();
  write_mesh(file, original, GetParam());

  const LoadedMesh loaded = read_mesh(file);
  EXPECT_EQ(loaded.format, GetParam());
  EXPECT_EQ(loaded.mesh.V.rows(), 5);  // the unreferenced vertex cannot survive a triangle soup
  expect_same_triangles(rounded_to_float(original), loaded.mesh);
}

INSTANTIATE_TEST_SUITE_P(BinaryAndAscii, StlRoundTrip,
                         testing::Values(MeshFormat::StlBinary, MeshFormat::StlAscii));

TEST(StlWrite, BinaryHeaderIsNotSolidAndNormalsAreComputedFromTheTriangle) {
  const fs::path file = test_dir() / "cube.stl";
  write_mesh(file, unit_cube(), MeshFormat::StlBinary);
  const std::string bytes = read_bytes(file);
  ASSERT_EQ(bytes.size(), 84u + 12u * 50u);
  EXPECT_NE(bytes.substr(0, 5), "solid");
  // Face 2 is (4, 5, 6) on the top: normal +z.
  float n[3];
  std::memcpy(n, bytes.data() + 84 + 2 * 50, sizeof n);
  EXPECT_EQ(n[0], 0.0f);
  EXPECT_EQ(n[1], 0.0f);
  EXPECT_EQ(n[2], 1.0f);
  // Face 4 is (0, 1, 5) on the front: normal -y.
  std::memcpy(n, bytes.data() + 84 + 4 * 50, sizeof n);
  EXPECT_EQ(n[1], -1.0f);
}

TEST(StlWrite, AsciiHasFacetNormals) {
  const fs::path file = test_dir() / "cube.stl";
  write_mesh(file, unit_cube(), MeshFormat::StlAscii);
  const std::string text = read_bytes(file);
  EXPECT_EQ(text.substr(0, 5), "solid");
  EXPECT_THAT(text, HasSubstr("facet normal 0 0 -1\n"));
  EXPECT_THAT(text, HasSubstr("facet normal 1 0 0\n"));
}

TEST(StlRead, TruncatedBinaryIsRefusedWithTheExpectedSize) {
  const fs::path file = test_dir() / "truncated.stl";
  std::string bytes = binary_stl(unit_cube(), "cube");
  bytes.resize(bytes.size() - 30);
  write_bytes(file, bytes);
  const std::string msg = read_error(file);
  EXPECT_THAT(msg, HasSubstr("truncated.stl"));
  EXPECT_THAT(msg, HasSubstr("declares 12 triangles"));
  EXPECT_THAT(msg, HasSubstr("684 bytes"));
}

TEST(StlRead, TruncatedBinaryWithSolidHeaderIsReportedAsBinary) {
  const fs::path file = test_dir() / "truncated_solid.stl";
  std::string bytes = binary_stl(unit_cube(), "solid cube");
  bytes.resize(bytes.size() - 50);
  write_bytes(file, bytes);
  EXPECT_THAT(read_error(file), HasSubstr("truncated_solid.stl: binary STL is truncated"));
}

TEST(StlRead, TinyAndEmptyFilesAreRefused) {
  const fs::path dir = test_dir();
  write_bytes(dir / "empty.stl", "");
  EXPECT_THAT(read_error(dir / "empty.stl"), HasSubstr("empty.stl: not an STL file"));
  write_bytes(dir / "tiny.stl", "hello");
  EXPECT_THAT(read_error(dir / "tiny.stl"), HasSubstr("tiny.stl: not an STL file"));
}

TEST(StlRead, BinaryNonFiniteCoordinateNamesTheByte) {
  const fs::path file = test_dir() / "nan.stl";
  TriangleMesh cube = unit_cube();
  cube.V(7, 1) = std::numeric_limits<double>::quiet_NaN();  // first used by face 3 = (4, 6, 7)
  write_bytes(file, binary_stl(cube, "cube"));
  const std::string msg = read_error(file);
  EXPECT_THAT(msg, HasSubstr("nan.stl"));
  EXPECT_THAT(msg, HasSubstr("triangle 3 vertex 2 has a non-finite coordinate"));
  EXPECT_THAT(msg, HasSubstr("byte " + std::to_string(84 + 3 * 50 + 12 + 2 * 12)));
}

TEST(StlRead, AsciiGarbageNamesTheLine) {
  const fs::path dir = test_dir();
  const std::string head = "solid s\nfacet normal 0 0 1\nouter loop\n";
  const std::string tail = "endloop\nendfacet\nendsolid s\n";

  write_bytes(dir / "word.stl", head + "vertex 0 0 0\nvertex 1 zero 0\nvertex 0 1 0\n" + tail);
  std::string msg = read_error(dir / "word.stl");
  EXPECT_THAT(msg, HasSubstr("word.stl: line 5"));
  EXPECT_THAT(msg, HasSubstr("'zero' is not a number"));

  write_bytes(dir / "four.stl",
              head + "vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nvertex 1 1 0\n" + tail);
  msg = read_error(dir / "four.stl");
  EXPECT_THAT(msg, HasSubstr("four.stl: line 7"));
  EXPECT_THAT(msg, HasSubstr("more than 3 vertices"));

  write_bytes(dir / "two.stl", head + "vertex 0 0 0\nvertex 1 0 0\n" + tail);
  EXPECT_THAT(read_error(dir / "two.stl"), HasSubstr("has 2 vertices"));

  write_bytes(dir / "inf.stl", head + "vertex 0 0 0\nvertex 1 0 0\nvertex inf 1 0\n" + tail);
  msg = read_error(dir / "inf.stl");
  EXPECT_THAT(msg, HasSubstr("inf.stl: line 6"));
  EXPECT_THAT(msg, HasSubstr("not finite"));

  write_bytes(dir / "huge.stl", head + "vertex 0 0 0\nvertex 1 0 0\nvertex 1e39 1 0\n" + tail);
  EXPECT_THAT(read_error(dir / "huge.stl"), HasSubstr("out of range for a float"));

  write_bytes(dir / "cut.stl", head + "vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\n");
  msg = read_error(dir / "cut.stl");
  EXPECT_THAT(msg, HasSubstr("cut.stl: line 8"));
  EXPECT_THAT(msg, HasSubstr("expected 'endfacet'"));

  write_bytes(dir / "noend.stl", head + "vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n");
  EXPECT_THAT(read_error(dir / "noend.stl"), HasSubstr("without 'endsolid'"));
}

// ---- PLY ---------------------------------------------------------------------------

class PlyRoundTrip : public testing::TestWithParam<MeshFormat> {};

TEST_P(PlyRoundTrip, KeepsVertexOrderFacesAndUnreferencedVerticesExactly) {
  const fs::path file = test_dir() / "mesh.ply";
  const TriangleMesh original = irregular_mesh();
  write_mesh(file, original, GetParam());

  const LoadedMesh loaded = read_mesh(file);
  EXPECT_EQ(loaded.format, GetParam());
  ASSERT_EQ(loaded.mesh.V.rows(), original.V.rows());
  EXPECT_EQ(loaded.mesh.F, original.F);
  EXPECT_LE((loaded.mesh.V - original.V).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(loaded.mesh.V, original.V);  // double properties: in fact bit-exact
}

INSTANTIATE_TEST_SUITE_P(BinaryAndAscii, PlyRoundTrip,
                         testing::Values(MeshFormat::PlyBinary, MeshFormat::PlyAscii));

TEST(PlyRead, BigEndianWithExtraPropertiesQuadsAndOtherElements) {
  const fs::path file = test_dir() / "big.ply";
  std::string bytes =
      "ply\n"
      "format binary_big_endian 1.0\n"
      "comment hand-made: extra vertex properties, a quad, an edge element\n"
      "element vertex 5\n"
      "property float x\n"
      "property uchar red\n"
      "property float y\n"
      "property list uchar float texcoord\n"
      "property double z\n"
      "element face 2\n"
      "property uchar flags\n"
      "property list uchar int vertex_indices\n"
      "element edge 1\n"
      "property int vertex1\n"
      "property int vertex2\n"
      "end_header\n";
  const float xy[5][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0.5f, 0.25f}};
  for (int v = 0; v < 5; ++v) {
    put(bytes, xy[v][0], true);
    put(bytes, std::uint8_t{200}, true);
    put(bytes, xy[v][1], true);
    put(bytes, std::uint8_t{2}, true);
    put(bytes, 0.5f, true);
    put(bytes, 0.75f, true);
    put(bytes, 10.0 + v, true);
  }
  put(bytes, std::uint8_t{7}, true);
  put(bytes, std::uint8_t{4}, true);  // quad 0 1 2 3
  for (int i : {0, 1, 2, 3}) put(bytes, std::int32_t{i}, true);
  put(bytes, std::uint8_t{7}, true);
  put(bytes, std::uint8_t{3}, true);
  for (int i : {4, 0, 2}) put(bytes, std::int32_t{i}, true);
  put(bytes, std::int32_t{0}, true);
  put(bytes, std::int32_t{1}, true);
  write_bytes(file, bytes);

  const LoadedMesh loaded = read_mesh(file);
  EXPECT_EQ(loaded.format, MeshFormat::PlyBinary);
  ASSERT_EQ(loaded.mesh.V.rows(), 5);
  EXPECT_EQ(loaded.mesh.V.row(2), Eigen::RowVector3d(1, 1, 12));
  EXPECT_EQ(loaded.mesh.V.row(4), Eigen::RowVector3d(0.5, 0.25, 14));
  ASSERT_EQ(loaded.mesh.F.rows(), 3);
  EXPECT_EQ(loaded.mesh.F.row(0), Eigen::RowVector3i(0, 1, 2));
  EXPECT_EQ(loaded.mesh.F.row(1), Eigen::RowVector3i(0, 2, 3));
  EXPECT_EQ(loaded.mesh.F.row(2), Eigen::RowVector3i(4, 0, 2));
}

TEST(PlyRead, AsciiWithSizedTypeNamesAndVertexIndexProperty) {
  const fs::path file = test_dir() / "ascii.ply";
  write_bytes(file,
              "ply\r\n"
              "format ascii 1.0\r\n"
              "obj_info from a scanner\r\n"
              "element vertex 4\r\n"
              "property float32 x\r\n"
              "property int16 y\r\n"
              "property float64 z\r\n"
              "property int8 quality\r\n"
              "element face 1\r\n"
              "property list uint8 uint32 vertex_index\r\n"
              "end_header\r\n"
              "0.5 -2 1e-3 -5\r\n"
              "1.5 3 0 1\r\n"
              "2.5 4 0 2\r\n"
              "3.5 5 0 3\r\n"
              "4 3 2 1 0\r\n");
  const LoadedMesh loaded = read_mesh(file);
  EXPECT_EQ(loaded.format, MeshFormat::PlyAscii);
  ASSERT_EQ(loaded.mesh.V.rows(), 4);
  EXPECT_EQ(loaded.mesh.V.row(0), Eigen::RowVector3d(0.5, -2, 1e-3));
  ASSERT_EQ(loaded.mesh.F.rows(), 2);
  EXPECT_EQ(loaded.mesh.F.row(0), Eigen::RowVector3i(3, 2, 1));
  EXPECT_EQ(loaded.mesh.F.row(1), Eigen::RowVector3i(3, 1, 0));
}

namespace {

std::string small_binary_ply(const std::string& vertex_count_text) {
  std::string bytes = "ply\nformat binary_little_endian 1.0\nelement vertex " + vertex_count_text +
                      "\nproperty float x\nproperty float y\nproperty float z\n"
                      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  for (int i = 0; i < 9; ++i) put(bytes, static_cast<float>(i));
  put(bytes, std::uint8_t{3});
  for (int i : {0, 1, 2}) put(bytes, std::int32_t{i});
  return bytes;
}

}  // namespace

TEST(PlyRead, AbsurdElementCountIsRefusedBeforeAllocating) {
  const fs::path dir = test_dir();
  write_bytes(dir / "absurd.ply", small_binary_ply("4000000000"));
  std::string msg = read_error(dir / "absurd.ply");
  EXPECT_THAT(msg, HasSubstr("absurd.ply: line 3"));
  EXPECT_THAT(msg, HasSubstr("4000000000"));

  write_bytes(dir / "absurd_ascii.ply",
              "ply\nformat ascii 1.0\nelement vertex 2000000000\nproperty float x\n"
              "property float y\nproperty float z\nend_header\n0 0 0\n");
  msg = read_error(dir / "absurd_ascii.ply");
  EXPECT_THAT(msg, HasSubstr("absurd_ascii.ply: line 3"));
  EXPECT_THAT(msg, HasSubstr("declares 2000000000 items"));

  // A per-face list length that cannot fit either.
  std::string bytes = "ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
                      "property float x\nproperty float y\nproperty float z\n"
                      "element face 1\nproperty list uint int vertex_indices\nend_header\n";
  for (int i = 0; i < 9; ++i) put(bytes, static_cast<float>(i));
  put(bytes, std::uint32_t{3000000000u});
  put(bytes, std::int32_t{0});
  write_bytes(dir / "long_list.ply", bytes);
  msg = read_error(dir / "long_list.ply");
  EXPECT_THAT(msg, HasSubstr("long_list.ply: byte"));
  EXPECT_THAT(msg, HasSubstr("list 'vertex_indices' of 3000000000 items does not fit"));
}

TEST(PlyRead, IndexOutOfRangeNamesFaceByteAndVertexCount) {
  const fs::path file = test_dir() / "aorta.ply";
  std::string bytes = small_binary_ply("3");
  const std::size_t header = bytes.find("end_header\n") + 11;
  const std::size_t index_at = header + 36 + 1 + 8;  // third index of face 0
  std::string bad;
  put(bad, std::int32_t{9001});
  bytes.replace(index_at, 4, bad);
  write_bytes(file, bytes);
  const std::string msg = read_error(file);
  EXPECT_THAT(msg, HasSubstr("aorta.ply: byte " + std::to_string(index_at)));
  EXPECT_THAT(msg, HasSubstr("face 0 has vertex index 9001 but the file has 3 vertices"));
}

TEST(PlyRead, TruncatedBinaryNamesTheByte) {
  const fs::path dir = test_dir();
  const std::string bytes = small_binary_ply("3");
  const std::size_t header = bytes.find("end_header\n") + 11;

  write_bytes(dir / "cut_face.ply", bytes.substr(0, bytes.size() - 2));
  EXPECT_THAT(read_error(dir / "cut_face.ply"),
              HasSubstr("cut_face.ply: byte " + std::to_string(header + 36) +
                        ": element 'face' item 0: list 'vertex_indices' of 3 items does not fit"));

  // Two faces declared, one present: the second face's count byte is missing.
  std::string one_face_short = bytes;
  one_face_short.replace(one_face_short.find("element face 1"), 14, "element face 2");
  write_bytes(dir / "cut_face2.ply", one_face_short);
  EXPECT_THAT(read_error(dir / "cut_face2.ply"),
              HasSubstr("cut_face2.ply: byte " + std::to_string(header + 49) +
                        ": element 'face' item 1: file ends early"));
}

TEST(PlyRead, MalformedFilesAreRefusedWithFileAndPlace) {
  const fs::path dir = test_dir();
  struct Case {
    std::string name, content, expected;
  };
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  const std::vector<Case> cases = {
      {"not_ply.ply", "solid x\n", "not a PLY file"},
      {"no_end.ply", "ply\nformat ascii 1.0\nelement vertex 0\n", "no 'end_header'"},
      {"no_format.ply", "ply\nelement vertex 0\n" + xyz + "end_header\n", "no 'format' line"},
      {"format.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n",
       "line 2: unknown PLY format 'binary_middle_endian'"},
      {"type.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n",
       "line 4: unknown property type 'float128'"},
      {"count.ply", "ply\nformat ascii 1.0\nelement vertex -3\n" + xyz + "end_header\n",
       "line 3: element count '-3' is not a non-negative integer"},
      {"no_z.ply",
       "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n",
       "line 3: element 'vertex' has no property 'z'"},
      {"no_vertex.ply", "ply\nformat ascii 1.0\nend_header\n", "no 'vertex' element"},
      {"no_indices.ply",
       "ply\nformat ascii 1.0\nelement vertex 0\n" + xyz +
           "element face 0\nproperty list uchar int corners\nend_header\n",
       "no list property 'vertex_indices'"},
      {"word.ply", "ply\nformat ascii 1.0\nelement vertex 2\n" + xyz + "end_header\n0 0 0\n1 one 0\n",
       "line 9: element 'vertex' item 1: 'one' is not a number"},
      {"nan.ply", "ply\nformat ascii 1.0\nelement vertex 2\n" + xyz + "end_header\n0 0 0\n1 nan 0\n",
       "line 9: vertex 1 has a non-finite coordinate"},
      {"short.ply", "ply\nformat ascii 1.0\nelement vertex 2\n" + xyz + "end_header\n0 0 0\n1 1\n",
       "file ends early"},
      {"extra.ply", "ply\nformat ascii 1.0\nelement vertex 1\n" + xyz + "end_header\n0 0 0\n1 1 1\n",
       "line 9: unexpected data '1' after the last element"},
      {"range.ply",
       "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz +
           "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
           "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
       "line 13: face 0 has vertex index 3 but the file has 3 vertices"},
      {"negative.ply",
       "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz +
           "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
           "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n",
       "face 0 has vertex index -1"},
      {"two.ply",
       "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz +
           "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
           "0 0 0\n1 0 0\n0 1 0\n2 0 1\n",
       "face 0 has 2 vertex indices"},
      {"neg_count.ply",
       "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz +
           "element face 1\nproperty list char int vertex_indices\nend_header\n"
           "0 0 0\n1 0 0\n0 1 0\n-1 0 1\n",
       "negative length -1"},
      {"float_index.ply",
       "ply\nformat ascii 1.0\nelement vertex 0\n" + xyz +
           "element face 0\nproperty list uchar float vertex_indices\nend_header\n",
       "must hold integers"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    write_bytes(dir / c.name, c.content);
    const std::string msg = read_error(dir / c.name);
    EXPECT_THAT(msg, HasSubstr(c.name + ": "));
    EXPECT_THAT(msg, HasSubstr(c.expected));
  }
}

// ---- OBJ ---------------------------------------------------------------------------

TEST(ObjRead, NegativeIndicesQuadsAndSlashFormsAreRead) {
  const fs::path file = test_dir() / "quad.obj";
  write_bytes(file,
              "# exported\nmtllib a.mtl\no thing\n"
              "v 0 0 0\nv 1 0 0\nv 1 1 0 1.0\nv 0 1 0\n"
              "vt 0 0\nvn 0 0 1\ng group\ns off\nusemtl red\n"
              "f 1/1/1 2/1/1 3/1/1 4/1/1\n"    // quad -> 2 triangles
              "v 0.5 0.5 1 0.2 0.3 0.4\n"      // vertex with a colour
              "f -1//1 -4//1 -3//1\n"          // relative: 5 2 3
              "f 3/1 5/1 4/1\n");
  const LoadedMesh loaded = read_mesh(file);
  EXPECT_EQ(loaded.format, MeshFormat::Obj);
  ASSERT_EQ(loaded.mesh.V.rows(), 5);
  EXPECT_EQ(loaded.mesh.V.row(4), Eigen::RowVector3d(0.5, 0.5, 1));
  ASSERT_EQ(loaded.mesh.F.rows(), 4);
  EXPECT_EQ(loaded.mesh.F.row(0), Eigen::RowVector3i(0, 1, 2));
  EXPECT_EQ(loaded.mesh.F.row(1), Eigen::RowVector3i(0, 2, 3));
  EXPECT_EQ(loaded.mesh.F.row(2), Eigen::RowVector3i(4, 1, 2));
  EXPECT_EQ(loaded.mesh.F.row(3), Eigen::RowVector3i(2, 4, 3));
}

TEST(ObjRoundTrip, KeepsVertexOrderFacesAndUnreferencedVerticesExactly) {
  const fs::path file = test_dir() / "mesh.obj";
  const TriangleMesh original = irregular_mesh();
  write_mesh(file, original, MeshFormat::Obj);
  const LoadedMesh loaded = read_mesh(file);
  ASSERT_EQ(loaded.mesh.V.rows(), original.V.rows());
  EXPECT_EQ(loaded.mesh.F, original.F);
  EXPECT_EQ(loaded.mesh.V, original.V);
}

TEST(ObjRead, MalformedFilesAreRefusedWithFileAndLine) {
  const fs::path dir = test_dir();
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  const std::vector<std::array<std::string, 3>> cases = {
      {"zero.obj", tri + "f 0 1 2\n", "line 4: face corner '0': vertex index 0"},
      {"range.obj", tri + "f 1 2 3\nf 1 2 9\n", "line 5: face refers to vertex 9 but the file has 3 vertices"},
      {"back.obj", tri + "f -1 -2 -4\n", "line 4: face corner '-4' refers back past the first vertex"},
      {"word.obj", "v 0 0 0\nv 1 zero 0\n", "line 2: coordinate 'zero' is not a number"},
      {"short.obj", "v 0 0\n", "line 1: vertex needs 3 coordinates"},
      {"inf.obj", "v 0 0 -inf\n", "line 1: coordinate '-inf' is not finite"},
      {"huge.obj", "v 0 0 1e400\n", "line 1: coordinate '1e400' is out of range"},
      {"edge.obj", tri + "f 1 2\n", "line 4: face has 2 vertices"},
      {"corner.obj", tri + "f 1 x 3\n", "line 4: face corner 'x' does not start with an integer"},
      {"junk.obj", "v 0 0 0 red\n", "line 1: unexpected 'red' after the vertex coordinates"},
  };
  for (const auto& [name, content, expected] : cases) {
    SCOPED_TRACE(name);
    write_bytes(dir / name, content);
    const std::string msg = read_error(dir / name);
    EXPECT_THAT(msg, HasSubstr(name + ": "));
    EXPECT_THAT(msg, HasSubstr(expected));
  }
}

// ---- dispatch ----------------------------------------------------------------------

TEST(ReadMesh, RefusesUnknownExtensionMissingFilesAndDirectories) {
  const fs::path dir = test_dir();
  write_bytes(dir / "mesh.off", "OFF\n3 1 0\n");
  EXPECT_THAT(read_error(dir / "mesh.off"), HasSubstr("mesh.off: unknown mesh extension '.off'"));
  EXPECT_THAT(read_error(dir / "missing.stl"), HasSubstr("missing.stl: file does not exist"));
  fs::create_directories(dir / "folder.ply");
  EXPECT_THAT(read_error(dir / "folder.ply"), HasSubstr("folder.ply: is a directory"));
}

TEST(ReadMesh, ExtensionIsCaseInsensitive) {
  const fs::path file = test_dir() / "CUBE.PLY";
  write_mesh(file, unit_cube(), MeshFormat::PlyAscii);
  EXPECT_EQ(read_mesh(file).mesh.F.rows(), 12);
}

TEST(FormatForExtension, ChoosesBinaryForStlAndPly) {
  EXPECT_EQ(format_for_extension("a/b.stl"), MeshFormat::StlBinary);
  EXPECT_EQ(format_for_extension("b.Ply"), MeshFormat::PlyBinary);
  EXPECT_EQ(format_for_extension("c.OBJ"), MeshFormat::Obj);
  EXPECT_THROW(format_for_extension("d.vtp"), evar::base::InputError);
}

TEST(WriteMesh, RefusesFaceIndicesOutsideTheVertices) {
  TriangleMesh m = unit_cube();
  m.F(3, 1) = 8;
  EXPECT_THROW(write_mesh(test_dir() / "bad.ply", m, MeshFormat::PlyBinary), std::invalid_argument);
}

TEST(WriteMesh, ThrowsWhenTheFileCannotBeWritten) {
  EXPECT_THROW(write_mesh(test_dir() / "no_such_dir" / "m.obj", unit_cube(), MeshFormat::Obj),
               std::runtime_error);
}

// ---- validation --------------------------------------------------------------------

TEST(ValidateMesh, AcceptsClosedAndOpenManifoldSurfaces) {
  EXPECT_NO_THROW(validate_mesh(unit_cube(), "cube"));
  TriangleMesh open = unit_cube();
  open.F.conservativeResize(10, 3);  // two faces removed: a boundary, still manifold
  EXPECT_NO_THROW(validate_mesh(open, "open cube"));

  // A 100 x 100 grid (20000 faces): every interior edge shared by exactly two faces.
  const int n = 100;
  TriangleMesh grid;
  grid.V.resize((n + 1) * (n + 1), 3);
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) grid.V.row(i * (n + 1) + j) << i, j, 0;
  }
  grid.F.resize(2 * n * n, 3);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const int a = i * (n + 1) + j, b = a + 1, c = a + n + 1, d = c + 1;
      grid.F.row(2 * (i * n + j)) << a, c, b;
      grid.F.row(2 * (i * n + j) + 1) << b, c, d;
    }
  }
  EXPECT_NO_THROW(validate_mesh(grid, "grid"));
}

// A PLY or OBJ written per triangle (each with corners of its own) is a cloud of loose
// triangles to the deformation, which then tore an iliac 22.8 mm apart: refused, saying
// how to weld it. Unreferenced copies (kept for vertex order) are not corners and pass.
TEST(ValidateMesh, RefusesTrianglesThatDoNotShareTheirCorners) {
  const TriangleMesh cube = unit_cube();
  TriangleMesh loose;
  loose.V.resize(3 * cube.F.rows(), 3);
  loose.F.resize(cube.F.rows(), 3);
  for (Eigen::Index f = 0; f < cube.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      loose.V.row(3 * f + k) = cube.V.row(cube.F(f, k));
      loose.F(f, k) = static_cast<int>(3 * f + k);
    }
  EXPECT_THAT(validate_error(loose), HasSubstr("lie exactly on another vertex without being joined"));
  EXPECT_THAT(validate_error(loose), HasSubstr("weld the mesh"));
  TriangleMesh spare = unit_cube();
  spare.V.conservativeResize(9, 3);
  spare.V.row(8) = spare.V.row(0);  // a copy no face uses
  EXPECT_NO_THROW(validate_mesh(spare, "cube with a spare vertex"));
}

TEST(ValidateMesh, NamesTheSourceAndTheOffendingItem) {
  TriangleMesh empty = unit_cube();
  empty.F.resize(0, 3);
  EXPECT_THAT(validate_error(empty), HasSubstr("patient7/aorta.stl: mesh has no faces"));

  TriangleMesh nan = unit_cube();
  nan.V(3, 2) = std::numeric_limits<double>::infinity();
  EXPECT_THAT(validate_error(nan), HasSubstr("patient7/aorta.stl: vertex 3 has a non-finite coordinate"));

  TriangleMesh range = unit_cube();
  range.F(7, 2) = 8;
  EXPECT_THAT(validate_error(range),
              HasSubstr("patient7/aorta.stl: face 7 has vertex index 8 but the mesh has 8 vertices"));
  range.F(7, 2) = -1;
  EXPECT_THAT(validate_error(range), HasSubstr("face 7 has vertex index -1"));

  TriangleMesh repeated = unit_cube();
  repeated.F.row(5) << 0, 5, 0;
  EXPECT_THAT(validate_error(repeated), HasSubstr("patient7/aorta.stl: face 5 repeats a vertex index (0, 5, 0)"));

  // A fin: a third face on the cube's edge (0, 1).
  TriangleMesh fin = unit_cube();
  fin.V.conservativeResize(9, 3);
  fin.V.row(8) << 0.5, -1, -1;
  fin.F.conservativeResize(13, 3);
  fin.F.row(12) << 0, 1, 8;
  EXPECT_THAT(validate_error(fin),
              HasSubstr("patient7/aorta.stl: non-manifold edge (0, 1) is shared by 3 faces (0, 4, 12)"));
}

TEST(MeanEdgeLength, AveragesEveryFaceEdge) {
  TriangleMesh tri;
  tri.V.resize(3, 3);
  tri.V << 0, 0, 0, 3, 0, 0, 0, 4, 0;
  tri.F.resize(1, 3);
  tri.F << 0, 1, 2;
  EXPECT_DOUBLE_EQ(mean_edge_length(tri), (3.0 + 4.0 + 5.0) / 3.0);
  // The cube: 12 faces, each with two unit edges and one diagonal.
  EXPECT_DOUBLE_EQ(mean_edge_length(unit_cube()), (2.0 + std::sqrt(2.0)) / 3.0);
  tri.F.resize(0, 3);
  EXPECT_EQ(mean_edge_length(tri), 0.0);
}

TEST(StlRead, SliversWhoseCornersWeldTogetherAreDropped) {
  // The cube plus one zero-area triangle with two bit-identical corners, as segmentation
  // exports contain: the sliver has no area, so the mesh stays the closed cube.
  TriangleMesh soup = unit_cube();
  soup.F.conservativeResize(soup.F.rows() + 1, 3);
  soup.F.row(soup.F.rows() - 1) << 0, 1, 1;
  const auto path = test_dir() / "sliver.stl";
  write_bytes(path, binary_stl(soup, "sliver"));
  const auto loaded = read_mesh(path);
  EXPECT_EQ(loaded.mesh.F.rows(), 12);
  EXPECT_NO_THROW(validate_mesh(loaded.mesh, path.string()));
}

TEST(ValidateMesh, RefusesCoordinatesBeyondAHundredMetres) {
  TriangleMesh far = unit_cube();
  far.V(3, 1) = 2e5;
  EXPECT_THAT(validate_error(far), HasSubstr("vertex 3 lies implausibly far from the origin"));
}

TEST(MeshTopology, ClosedMeshesAndMedianEdgeLength) {
  const TriangleMesh cube = unit_cube();
  EXPECT_TRUE(is_closed(cube));
  TriangleMesh open = cube;
  open.F.conservativeResize(open.F.rows() - 1, 3);
  EXPECT_FALSE(is_closed(open));
  // Cube edges are 1 (12 of 18 per 6 faces... 24 of 36 half-edges) or sqrt(2) (diagonals).
  EXPECT_DOUBLE_EQ(median_edge_length(cube), 1.0);
}
