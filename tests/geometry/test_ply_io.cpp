// PLY reading and writing: both endiannesses, extra properties and elements, round trips,
// and malformed files refused by an InputError that names the file and the place.
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

