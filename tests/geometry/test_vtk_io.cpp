// VTK legacy polydata (.vtk), 3D Slicer's default model format: the files VTK writes
// (versions 4.2 and 5.1, ASCII and BINARY, polygons and triangle strips, attribute and
// metadata blocks) are read with their vertex order, evarnode's own round-trip exactly,
// and malformed files are refused naming the file and the line or byte.
#include <Eigen/Geometry>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>

#include "evar/base/input_error.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "support/error_message.hpp"
#include "support/file_bytes.hpp"
#include "support/temp_dir.hpp"

namespace fs = std::filesystem;
using evar::geometry::MeshFormat;
using evar::geometry::MeshSpace;
using evar::geometry::read_mesh;
using evar::geometry::TriangleMesh;
using evar::geometry::write_mesh;
using evar::test::TempDir;
using testing::HasSubstr;

namespace {

// `bytes` as a file `name` in the test's own scratch folder.
fs::path file_of(const TempDir& dir, const std::string& name, const std::string& bytes) {
  const fs::path path = dir.path / name;
  evar::test::write_bytes(path, bytes);
  return path;
}

std::string read_error(const fs::path& path) {
  return evar::test::error_message([&] { read_mesh(path); }, "read_mesh(" + path.string() + ") did not throw evar::base::InputError");
}

template <class T>
void put_be(std::string& out, T value) {
  char b[sizeof(T)];
  std::memcpy(b, &value, sizeof(T));
  std::reverse(b, b + sizeof(T));  // the test machine is little-endian (x86-64)
  out.append(b, sizeof(T));
}

// A unit square made of two triangles plus an unreferenced fifth point: the reader must
// keep the file's numbering.
constexpr const char* kSquarePoints = "0 0 0 1 0 0 1 1 0\n0 1 0 7 7 7\n";

void expect_square(const TriangleMesh& m) {
  ASSERT_EQ(m.V.rows(), 5);
  EXPECT_EQ(m.V(2, 0), 1.0);
  EXPECT_EQ(m.V(2, 1), 1.0);
  EXPECT_EQ(m.V(4, 2), 7.0);
  ASSERT_EQ(m.F.rows(), 2);
  EXPECT_EQ(m.F(0, 0), 0);
  EXPECT_EQ(m.F(0, 1), 1);
  EXPECT_EQ(m.F(0, 2), 2);
  EXPECT_EQ(m.F(1, 0), 0);
  EXPECT_EQ(m.F(1, 1), 2);
  EXPECT_EQ(m.F(1, 2), 3);
}

}  // namespace

// As 3D Slicer saves a model (vtkPolyDataWriter, version 4.2, ASCII), with the normals
// and the array metadata VTK 9 adds after the points.
TEST(VtkRead, ASlicerAsciiFileWithPointDataAndMetadata) {
  const TempDir dir;
  const std::string text = std::string("# vtk DataFile Version 4.2\n3D Slicer output. SPACE=LPS\nASCII\n") +
                           "DATASET POLYDATA\nPOINTS 5 float\n" + kSquarePoints +
                           "METADATA\nINFORMATION 2\nNAME L2_NORM_RANGE LOCATION vtkDataArray\nDATA 2 0 12.1244\n"
                           "NAME L2_NORM_FINITE_RANGE LOCATION vtkDataArray\nDATA 2 0 12.1244\n\n"
                           "POLYGONS 1 5\n4 0 1 2 3\n"
                           "POINT_DATA 5\nNORMALS Normals float\n0 0 1 0 0 1 0 0 1 0 0 1 0 0 1\n";
  const auto loaded = read_mesh(file_of(dir, "model.vtk", text));
  EXPECT_EQ(loaded.format, MeshFormat::VtkAscii);
  EXPECT_EQ(loaded.space, MeshSpace::Lps);
  expect_square(loaded.mesh);  // the quad, fan-triangulated
}

// BINARY (big-endian), a FIELD block before the points, and a triangle strip whose
// second triangle is turned to face the same way.
TEST(VtkRead, BinaryWithFieldDataAndATriangleStrip) {
  const TempDir dir;
  std::string b = "# vtk DataFile Version 4.2\nvtk output\nBINARY\nDATASET POLYDATA\n"
                  "FIELD FieldData 1\nLabel 1 2 double\n";
  put_be(b, 4.5);
  put_be(b, -1.0);
  b += "\nPOINTS 5 double\n";
  for (const double v : {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 7, 7, 7}) put_be(b, v);
  b += "\nTRIANGLE_STRIPS 1 5\n";
  for (const std::int32_t v : {4, 0, 1, 3, 2}) put_be(b, v);
  b += "\nCELL_DATA 2\n";
  const auto loaded = read_mesh(file_of(dir, "strip.vtk", b));
  EXPECT_EQ(loaded.format, MeshFormat::VtkBinary);
  EXPECT_EQ(loaded.space, MeshSpace::Undeclared);
  const auto& m = loaded.mesh;
  ASSERT_EQ(m.F.rows(), 2);
  // (0, 1, 3), then (3, 1, 2) turned from (1, 3, 2): both face +z.
  for (Eigen::Index f = 0; f < 2; ++f) {
    const Eigen::Vector3d a = m.V.row(m.F(f, 0)), c1 = m.V.row(m.F(f, 1)), c2 = m.V.row(m.F(f, 2));
    EXPECT_GT((c1 - a).cross(c2 - a).z(), 0.0) << "triangle " << f;
  }
}

// VTK 9's own layout (version 5.1): OFFSETS and CONNECTIVITY arrays, ASCII and BINARY.
TEST(VtkRead, Version51OffsetsAndConnectivity) {
  const TempDir dir;
  const std::string ascii = std::string("# vtk DataFile Version 5.1\nvtk output\nASCII\nDATASET POLYDATA\n") +
                            "POINTS 5 float\n" + kSquarePoints +
                            "POLYGONS 3 6\nOFFSETS vtktypeint64\n0 3 6\nCONNECTIVITY vtktypeint64\n0 1 2 0 2 3\n";
  expect_square(read_mesh(file_of(dir, "a51.vtk", ascii)).mesh);

  std::string b = "# vtk DataFile Version 5.1\nvtk output\nBINARY\nDATASET POLYDATA\nPOINTS 5 float\n";
  for (const float v : {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 7, 7, 7}) put_be(b, v);
  b += "\nPOLYGONS 3 6\nOFFSETS vtktypeint64\n";
  for (const std::int64_t v : {0, 3, 6}) put_be(b, v);
  b += "\nCONNECTIVITY vtktypeint64\n";
  for (const std::int64_t v : {0, 1, 2, 0, 2, 3}) put_be(b, v);
  b += "\n";
  expect_square(read_mesh(file_of(dir, "b51.vtk", b)).mesh);
}

TEST(VtkRead, ASlicerFileInRasIsReadIntoLps) {
  const TempDir dir;
  const std::string text = std::string("# vtk DataFile Version 4.2\n3D Slicer output. SPACE=RAS\nASCII\n") +
                           "DATASET POLYDATA\nPOINTS 3 float\n-10 -20 30 -11 -20 30 -10 -21 31\nPOLYGONS 1 4\n3 0 1 2\n";
  const auto loaded = read_mesh(file_of(dir, "ras.vtk", text));
  EXPECT_EQ(loaded.space, MeshSpace::Ras);
  EXPECT_EQ(loaded.mesh.V(0, 0), 10.0);
  EXPECT_EQ(loaded.mesh.V(0, 1), 20.0);
  EXPECT_EQ(loaded.mesh.V(0, 2), 30.0);
}

// Lines and vertices are cells but not faces: skipped, their indices still checked.
TEST(VtkRead, LinesAndVerticesAreNotFaces) {
  const TempDir dir;
  const std::string text = std::string("# vtk DataFile Version 4.2\nt\nASCII\nDATASET POLYDATA\nPOINTS 5 float\n") +
                           kSquarePoints + "VERTICES 1 2\n1 4\nLINES 1 3\n2 0 4\nPOLYGONS 2 8\n3 0 1 2\n3 0 2 3\n";
  expect_square(read_mesh(file_of(dir, "lines.vtk", text)).mesh);
}

// What else VTK 8/9 writes around the geometry: FIELD arrays of vtkIdType, bits and
// strings (binary strings carry a length prefix), component names that may be empty
// lines inside METADATA, and an empty cell section in a 5.1 file.
TEST(VtkRead, FieldArraysComponentNamesAndEmptySectionsAsVtkWritesThem) {
  const TempDir dir;
  const std::string ascii = std::string("# vtk DataFile Version 5.1\nvtk output\nASCII\nDATASET POLYDATA\n") +
                            "FIELD FieldData 3\nIds 1 2 vtkIdType\n7 8\nFlags 1 3 bit\n1 0 1\nNames 1 1 string\nleft%20iliac\n" +
                            "POINTS 5 float\n" + kSquarePoints +
                            "METADATA\nCOMPONENT_NAMES\nX\n\nZ\nINFORMATION 1\nNAME L2_NORM_RANGE LOCATION vtkDataArray\n"
                            "DATA 2 0 12.1\n\nLINES 0 0\nPOLYGONS 3 6\nOFFSETS vtktypeint64\n0 3 6\n"
                            "CONNECTIVITY vtktypeint64\n0 1 2 0 2 3\n";
  expect_square(read_mesh(file_of(dir, "field.vtk", ascii)).mesh);

  std::string b = "# vtk DataFile Version 4.2\nvtk output\nBINARY\nDATASET POLYDATA\nFIELD FieldData 2\n"
                  "Names 1 2 string\n";
  b += static_cast<char>(0xC0 | 5);  // a 1-byte length: 5
  b += "iliac";
  b += static_cast<char>(0x80 | 1);  // a 2-byte length: 0x12C = 300
  b += static_cast<char>(44);
  b += std::string(300, 'x');
  b += "\nIds 1 1 vtkIdType\n";
  put_be(b, std::int32_t{7});
  b += "\nPOINTS 5 float\n";
  for (const float v : {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 7, 7, 7}) put_be(b, v);
  b += "\nPOLYGONS 2 8\n";
  for (const std::int32_t v : {3, 0, 1, 2, 3, 0, 2, 3}) put_be(b, v);
  b += "\n";
  expect_square(read_mesh(file_of(dir, "field_binary.vtk", b)).mesh);
}

TEST(VtkRead, BadOffsetsAndLineIndicesAreRefusedOnTheirLine) {
  const TempDir dir;
  const std::string head = "# vtk DataFile Version 5.1\nt\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0 1 0 0 1 1 0\n";
  EXPECT_THAT(read_error(file_of(dir, "first.vtk", head + "POLYGONS 2 3\nOFFSETS vtktypeint64\n1 3\n"
                                                          "CONNECTIVITY vtktypeint64\n0 1 2\n")),
              HasSubstr("line 8: POLYGONS: the first offset is 1, not 0"));
  EXPECT_THAT(read_error(file_of(dir, "back.vtk", head + "POLYGONS 3 3\nOFFSETS vtktypeint64\n0 3 2\n"
                                                         "CONNECTIVITY vtktypeint64\n0 1 2\n")),
              HasSubstr("line 8: POLYGONS: offset 2 goes back (2 after 3)"));
  EXPECT_THAT(read_error(file_of(dir, "last.vtk", head + "POLYGONS 2 4\nOFFSETS vtktypeint64\n0 3\n"
                                                         "CONNECTIVITY vtktypeint64\n0 1 2 0\n")),
              HasSubstr("line 8: POLYGONS: the last offset is 3 but there are 4 indices"));
  const std::string v4 = "# vtk DataFile Version 4.2\nt\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0 1 0 0 1 1 0\n";
  EXPECT_THAT(read_error(file_of(dir, "line.vtk", v4 + "LINES 1 3\n2 0 9\nPOLYGONS 1 4\n3 0 1 2\n")),
              HasSubstr("line 8: LINES: cell 0 has point index 9 but the file has 3 points"));
  // A bad index is named on its own line, not on the section's: a model has thousands.
  EXPECT_THAT(read_error(file_of(dir, "third.vtk", v4 + "POLYGONS 3 12\n3 0 1 2\n3 0 2 1\n3 2 1\n7\n")),
              HasSubstr("line 11: POLYGONS: cell 2 has point index 7 but the file has 3 points"));
  EXPECT_THAT(read_error(file_of(dir, "v5.vtk", head + "POLYGONS 3 6\nOFFSETS vtktypeint64\n0 3 6\n"
                                                       "CONNECTIVITY vtktypeint64\n0 1 2\n2 1 5\n")),
              HasSubstr("line 12: POLYGONS: cell 1 has point index 5 but the file has 3 points"));
}

TEST(VtkRoundTrip, KeepsVertexOrderFacesAndDoublesExactly) {
  const TempDir dir;
  TriangleMesh m;
  m.V.resize(5, 3);
  m.V << 12.345678901234567, -98.76543210987654, 0.1, 1e-7, 3.0 / 7.0, -250.5, 77.7, 0.3, 1.0 / 3.0, -0.0, 5.5,
      6.25, 999.999, -999.999, 42.0;
  m.F.resize(2, 3);
  m.F << 3, 0, 4, 4, 0, 1;  // vertex 2 unreferenced
  for (const MeshFormat f : {MeshFormat::VtkAscii, MeshFormat::VtkBinary}) {
    const fs::path file = dir.path / (f == MeshFormat::VtkAscii ? "a.vtk" : "b.vtk");
    write_mesh(file, m, f);
    const auto back = read_mesh(file);
    EXPECT_EQ(back.format, f);
    EXPECT_EQ(back.space, MeshSpace::Lps);
    EXPECT_EQ(back.mesh.V, m.V);
    EXPECT_TRUE(std::signbit(back.mesh.V(3, 0)));  // -0 stays -0 (== cannot tell)
    EXPECT_EQ(back.mesh.F, m.F);
  }
  EXPECT_EQ(evar::geometry::format_for_extension("m.VTK"), MeshFormat::VtkBinary);
}

TEST(VtkRead, MalformedFilesAreRefusedWithFileAndPlace) {
  const TempDir dir;
  const std::string head = "# vtk DataFile Version 4.2\nt\nASCII\nDATASET POLYDATA\n";
  struct Case {
    std::string text, expected;
  };
  const Case cases[] = {
      {"solid x\n", "not a VTK legacy file"},
      {"# vtk DataFile Version 4.2\nt\nTEXT\nDATASET POLYDATA\n", "line 3: the third line must be ASCII or BINARY"},
      {"# vtk DataFile Version 4.2\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 0 float\n",
       "only POLYDATA is read as a mesh; this file's dataset is 'UNSTRUCTURED_GRID'"},
      {head + "POINTS 3 float\n0 0 0 1 0 0 1 1 0\nPOLYGONS 1 4\n3 0 1 9\n",
       "POLYGONS: cell 0 has point index 9 but the file has 3 points"},
      {head + "POINTS 3 float\n0 0 0 1 0 0 1 1 0\nPOLYGONS 1 3\n2 0 1\n", "POLYGONS: cell 0 has 2 points; a face needs 3"},
      {head + "POINTS 3 float\n0 0 0 1 0 nan 1 1 0\n", "line 6: point 1 has a non-finite coordinate"},
      {head + "POINTS 3 float\n0 0 0 1 0 x 1 1 0\n", "line 6: POINTS: 'x' is not a number"},
      {head + "POINTS 3 float\n0 0 0 1 0 0\n", "the file ends inside its POINTS"},
      {head + "POINTS 4000000000 float\n0 0 0\n", "POINTS count 4000000000 cannot fit in the"},
      {head + "POINTS 3 bit\n0 0 0 1 0 0 1 1 0\n", "unknown value type 'bit'"},
      {head + "POLYGONS 1 4\n3 0 1 2\n", "POLYGONS comes before POINTS"},
      {head + "POINTS 3 float\n0 0 0 1 0 0 1 1 0\nPOLYGONS 2 4\n3 0 1 2\n", "declares 2 cells but its 4 values hold 1"},
      {head + "POINTS 3 float\n0 0 0 1 0 0 1 1 0\nQUADS 1\n", "unexpected 'QUADS'"},
      {head, "the file has no POINTS section"},
  };
  for (const Case& c : cases) {
    const fs::path path = file_of(dir, "bad.vtk", c.text);
    const std::string error = read_error(path);
    EXPECT_THAT(error, HasSubstr(path.string())) << c.text;
    EXPECT_THAT(error, HasSubstr(c.expected)) << c.text;
  }
}

TEST(VtkRead, TruncatedBinaryNamesTheByte) {
  const TempDir dir;
  std::string b = "# vtk DataFile Version 4.2\nt\nBINARY\nDATASET POLYDATA\nPOINTS 3 float\n";
  for (const float v : {0, 0, 0, 1, 0}) put_be(b, v);  // 5 of the 9 floats
  const std::string error = read_error(file_of(dir, "cut.vtk", b));
  EXPECT_THAT(error, HasSubstr("POINTS 3 of 4 bytes each cannot fit in the rest of the file"));
  std::string v5 = "# vtk DataFile Version 5.1\nt\nBINARY\nDATASET POLYDATA\nPOINTS 3 float\n";
  for (const float v : {0, 0, 0, 1, 0, 0, 1, 1, 0}) put_be(v5, v);
  v5 += "\nPOLYGONS 2 3\nOFFSETS vtktypeint64\n";
  const std::size_t offsets_at = v5.size();
  put_be(v5, std::int64_t{0});
  EXPECT_THAT(read_error(file_of(dir, "cut51.vtk", v5)),
              HasSubstr("byte " + std::to_string(offsets_at) + ": the file ends inside its POLYGONS OFFSETS"));
}

TEST(VtkRead, ABadIndexInBinaryNamesItsByte) {
  const TempDir dir;
  std::string b = "# vtk DataFile Version 4.2\nt\nBINARY\nDATASET POLYDATA\nPOINTS 3 float\n";
  for (const float v : {0, 0, 0, 1, 0, 0, 1, 1, 0}) put_be(b, v);
  b += "\nPOLYGONS 2 8\n";
  for (const std::int32_t v : {3, 0, 1, 2, 3, 2, 1}) put_be(b, v);
  const std::size_t bad_at = b.size();  // cell 1's third index
  put_be(b, std::int32_t{3});
  EXPECT_THAT(read_error(file_of(dir, "index.vtk", b)),
              HasSubstr("byte " + std::to_string(bad_at) + ": POLYGONS: cell 1 has point index 3 but the file has 3 points"));
  // VTK 9's layout with 8-byte indices: the place steps by the index type's size.
  std::string v5 = "# vtk DataFile Version 5.1\nt\nBINARY\nDATASET POLYDATA\nPOINTS 3 float\n";
  for (const float v : {0, 0, 0, 1, 0, 0, 1, 1, 0}) put_be(v5, v);
  v5 += "\nPOLYGONS 3 6\nOFFSETS vtktypeint64\n";
  for (const std::int64_t v : {0, 3, 6}) put_be(v5, v);
  v5 += "\nCONNECTIVITY vtktypeint64\n";
  for (const std::int64_t v : {0, 1, 2, 2, 1}) put_be(v5, v);
  const std::size_t bad51_at = v5.size();  // cell 1's third index
  put_be(v5, std::int64_t{4});
  v5 += "\n";
  EXPECT_THAT(read_error(file_of(dir, "index51.vtk", v5)),
              HasSubstr("byte " + std::to_string(bad51_at) + ": POLYGONS: cell 1 has point index 4 but the file has 3 points"));
}
