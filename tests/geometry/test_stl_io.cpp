// STL reading and writing: binary and ASCII detection, welding, round trips, and malformed
// files refused by an InputError that names the file and the byte or line.
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
#include "geometry/mesh_io_fixtures.hpp"
#include "support/file_bytes.hpp"

using namespace evar::test::mesh_io;  // its names, the readers' and writers' too

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
