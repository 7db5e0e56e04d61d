// The coordinate system a mesh file declares (SPACE=LPS / SPACE=RAS, as 3D Slicer writes
// it into every mesh it saves): RAS files are read into LPS and written back as RAS, every
// file evarnode writes says which it is, and a file that says both is refused.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <sstream>
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
using evar::test::read_bytes;
using evar::test::TempDir;
using evar::test::write_bytes;
using testing::HasSubstr;

namespace {

// A tetrahedron well off every axis, so a sign flip of x or y shows; corners are floats
// (STL's precision), so every format gives them back exactly.
TriangleMesh tetrahedron() {
  TriangleMesh m;
  m.V.resize(4, 3);
  m.V << 12.5, -40.25, 101.0, 30.75, -35.5, 99.0, 18.0, -22.125, 97.5, 20.5, -33.0, 120.25;
  m.F.resize(4, 3);
  m.F << 0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2;
  return m;
}

TriangleMesh in_ras(TriangleMesh m) {
  m.V.col(0) = -m.V.col(0);
  m.V.col(1) = -m.V.col(1);
  return m;
}

// The files 3D Slicer (vtkMRMLModelStorageNode) writes for `m`: its header text is
// "3D Slicer output. SPACE=<space>" (binary and ASCII STL, OBJ, the VTK title), and a
// PLY gets the comment "SPACE=<space>". Coordinates as given (the caller flips them for RAS).
std::string slicer_file(MeshFormat format, const TriangleMesh& m, const std::string& space) {
  const std::string header = "3D Slicer output. SPACE=" + space;
  std::ostringstream out;
  switch (format) {
    case MeshFormat::StlBinary: {
      std::string b = header;
      b.resize(80, ' ');
      const auto n = static_cast<std::uint32_t>(m.F.rows());
      b.append(reinterpret_cast<const char*>(&n), 4);
      for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
        float v[12] = {};
        for (int c = 0; c < 3; ++c)
          for (int k = 0; k < 3; ++k) v[3 + 3 * c + k] = static_cast<float>(m.V(m.F(f, c), k));
        b.append(reinterpret_cast<const char*>(v), sizeof v);
        b.append(2, '\0');
      }
      return b;
    }
    case MeshFormat::StlAscii:
      out << "solid " << header << "\n";
      for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
        out << " facet normal 0 0 0\n  outer loop\n";
        for (int c = 0; c < 3; ++c)
          out << "   vertex " << m.V(m.F(f, c), 0) << ' ' << m.V(m.F(f, c), 1) << ' ' << m.V(m.F(f, c), 2) << "\n";
        out << "  endloop\n endfacet\n";
      }
      out << "endsolid\n";
      return out.str();
    case MeshFormat::PlyAscii:
    case MeshFormat::PlyBinary:
      out << "ply\nformat ascii 1.0\ncomment VTK generated PLY File\ncomment SPACE=" << space
          << "\nelement vertex " << m.V.rows() << "\nproperty float x\nproperty float y\nproperty float z\n"
          << "element face " << m.F.rows() << "\nproperty list uchar int vertex_indices\nend_header\n";
      for (Eigen::Index i = 0; i < m.V.rows(); ++i) out << m.V(i, 0) << ' ' << m.V(i, 1) << ' ' << m.V(i, 2) << "\n";
      for (Eigen::Index f = 0; f < m.F.rows(); ++f) out << "3 " << m.F(f, 0) << ' ' << m.F(f, 1) << ' ' << m.F(f, 2) << "\n";
      return out.str();
    case MeshFormat::Obj:
      out << "# " << header << "\n\nmtllib model.mtl\n";
      for (Eigen::Index i = 0; i < m.V.rows(); ++i) out << "v " << m.V(i, 0) << ' ' << m.V(i, 1) << ' ' << m.V(i, 2) << "\n";
      for (Eigen::Index f = 0; f < m.F.rows(); ++f)
        out << "f " << m.F(f, 0) + 1 << ' ' << m.F(f, 1) + 1 << ' ' << m.F(f, 2) + 1 << "\n";
      return out.str();
    case MeshFormat::VtkAscii:
    case MeshFormat::VtkBinary:  // vtkPolyDataWriter, version 4.2 (ASCII here either way)
      out << "# vtk DataFile Version 4.2\n" << header << "\nASCII\nDATASET POLYDATA\nPOINTS " << m.V.rows()
          << " float\n";
      for (Eigen::Index i = 0; i < m.V.rows(); ++i) out << m.V(i, 0) << ' ' << m.V(i, 1) << ' ' << m.V(i, 2) << "\n";
      out << "POLYGONS " << m.F.rows() << ' ' << 4 * m.F.rows() << "\n";
      for (Eigen::Index f = 0; f < m.F.rows(); ++f) out << "3 " << m.F(f, 0) << ' ' << m.F(f, 1) << ' ' << m.F(f, 2) << "\n";
      return out.str();
    case MeshFormat::Vtp: {  // vtkXMLPolyDataWriter with the field data Slicer adds (ASCII here)
      out << "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" "
             "header_type=\"UInt64\">\n<PolyData>\n<FieldData>\n<Array type=\"String\" Name=\"SPACE\" "
             "NumberOfTuples=\"1\" format=\"ascii\">";
      for (const char c : space) out << static_cast<int>(c) << ' ';
      out << "0</Array>\n</FieldData>\n<Piece NumberOfPoints=\"" << m.V.rows() << "\" NumberOfPolys=\"" << m.F.rows()
          << "\">\n<Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"ascii\">";
      for (Eigen::Index i = 0; i < m.V.rows(); ++i) out << m.V(i, 0) << ' ' << m.V(i, 1) << ' ' << m.V(i, 2) << ' ';
      out << "</DataArray></Points>\n<Polys><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">";
      for (Eigen::Index f = 0; f < m.F.rows(); ++f) out << m.F(f, 0) << ' ' << m.F(f, 1) << ' ' << m.F(f, 2) << ' ';
      out << "</DataArray><DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">";
      for (Eigen::Index f = 0; f < m.F.rows(); ++f) out << 3 * (f + 1) << ' ';
      out << "</DataArray></Polys>\n</Piece>\n</PolyData>\n</VTKFile>\n";
      return out.str();
    }
  }
  return {};
}

const char* extension(MeshFormat f) {
  if (f == MeshFormat::VtkAscii || f == MeshFormat::VtkBinary) return ".vtk";
  if (f == MeshFormat::Vtp) return ".vtp";
  return f == MeshFormat::Obj ? ".obj" : (f == MeshFormat::PlyAscii || f == MeshFormat::PlyBinary) ? ".ply" : ".stl";
}

// Same corners, face by face (STL renumbers vertices as it welds them).
void expect_same_triangles(const TriangleMesh& expected, const TriangleMesh& actual) {
  ASSERT_EQ(expected.F.rows(), actual.F.rows());
  for (Eigen::Index f = 0; f < expected.F.rows(); ++f)
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 3; ++k)
        EXPECT_EQ(expected.V(expected.F(f, c), k), actual.V(actual.F(f, c), k)) << "face " << f << " corner " << c;
}

class MeshSpaceOfEachFormat : public testing::TestWithParam<MeshFormat> {};

}  // namespace

// Without the tag a model saved from Slicer in RAS would come in turned 180° about the
// patient's long axis: its left iliac on the right, in front of the spine.
TEST_P(MeshSpaceOfEachFormat, ASlicerFileInRasIsReadIntoLps) {
  const TempDir dir;
  const fs::path file = dir.path / (std::string("model") + extension(GetParam()));
  write_bytes(file, slicer_file(GetParam(), in_ras(tetrahedron()), "RAS"));
  const auto loaded = read_mesh(file);
  EXPECT_EQ(loaded.space, MeshSpace::Ras);
  expect_same_triangles(tetrahedron(), loaded.mesh);
}

TEST_P(MeshSpaceOfEachFormat, ASlicerFileInLpsIsReadAsItIs) {
  const TempDir dir;
  const fs::path file = dir.path / (std::string("model") + extension(GetParam()));
  write_bytes(file, slicer_file(GetParam(), tetrahedron(), "LPS"));
  const auto loaded = read_mesh(file);
  EXPECT_EQ(loaded.space, MeshSpace::Lps);
  expect_same_triangles(tetrahedron(), loaded.mesh);
}

// What evarnode writes says which space it is in, and reads back to the same LPS mesh;
// a RAS file holds the RAS coordinates (as Slicer's reader expects them).
TEST_P(MeshSpaceOfEachFormat, WrittenFilesDeclareTheirSpaceAndReadBackTheSame) {
  const TempDir dir;
  for (const MeshSpace space : {MeshSpace::Lps, MeshSpace::Ras, MeshSpace::Undeclared}) {
    const fs::path file = dir.path / ("out" + std::to_string(static_cast<int>(space)) + extension(GetParam()));
    write_mesh(file, tetrahedron(), GetParam(), space);
    const std::string bytes = read_bytes(file);
    const bool ras = space == MeshSpace::Ras;
    EXPECT_THAT(bytes.substr(0, 120), HasSubstr(ras ? "SPACE=RAS" : "SPACE=LPS"));
    const auto back = read_mesh(file);
    EXPECT_EQ(back.space, ras ? MeshSpace::Ras : MeshSpace::Lps);
    expect_same_triangles(tetrahedron(), back.mesh);
    if (GetParam() == MeshFormat::Obj) {  // the first vertex as it stands in the file
      EXPECT_THAT(bytes, HasSubstr(ras ? "\nv -12.5 40.25 101\n" : "\nv 12.5 -40.25 101\n"));
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Formats, MeshSpaceOfEachFormat,
                         testing::Values(MeshFormat::StlBinary, MeshFormat::StlAscii, MeshFormat::PlyAscii, MeshFormat::Obj,
                                         MeshFormat::VtkBinary));

TEST(MeshSpace, AFileWithoutATagIsLpsAndSaysItIsUndeclared) {
  const TempDir dir;
  const fs::path file = dir.path / "plain.obj";
  write_bytes(file, "# made by hand\nv 1 2 3\nv 4 5 6\nv 7 8 10\nf 1 2 3\n");
  const auto loaded = read_mesh(file);
  EXPECT_EQ(loaded.space, MeshSpace::Undeclared);
  EXPECT_EQ(loaded.mesh.V(0, 0), 1.0);
  EXPECT_EQ(loaded.mesh.V(0, 1), 2.0);
}

// Only what Slicer's readers (VTK's) take for the header counts: an OBJ's comment lines
// from the first line on without a break, every ASCII STL solid's name, a binary STL
// header up to its first NUL byte.
TEST(MeshSpace, OnlyWhatSlicersReadersTakeForTheHeaderCounts) {
  const TempDir tmp;
  const fs::path dir = tmp.path;
  write_bytes(dir / "late.obj", "v 1 2 3\n# SPACE=RAS\nv 4 5 6\nv 7 8 10\nf 1 2 3\n");
  EXPECT_EQ(read_mesh(dir / "late.obj").space, MeshSpace::Undeclared);
  EXPECT_EQ(read_mesh(dir / "late.obj").mesh.V(0, 0), 1.0);
  write_bytes(dir / "gap.obj", "# made by X\n\n# SPACE=RAS\nv 1 2 3\nv 4 5 6\nv 7 8 10\nf 1 2 3\n");
  EXPECT_EQ(read_mesh(dir / "gap.obj").space, MeshSpace::Undeclared);
  write_bytes(dir / "block.obj", "# made by X\n# SPACE=RAS\nv 1 2 3\nv 4 5 6\nv 7 8 10\nf 1 2 3\n");
  EXPECT_EQ(read_mesh(dir / "block.obj").space, MeshSpace::Ras);

  std::string two_solids = slicer_file(MeshFormat::StlAscii, tetrahedron(), "LPS");
  two_solids.replace(0, two_solids.find('\n'), "solid first");
  two_solids += "solid second SPACE=RAS\nendsolid\n";
  write_bytes(dir / "two.stl", two_solids);
  EXPECT_EQ(read_mesh(dir / "two.stl").space, MeshSpace::Ras);

  std::string binary = slicer_file(MeshFormat::StlBinary, tetrahedron(), "LPS");
  std::string header("evarnode\0SPACE=RAS", 18);  // after the NUL: not in the header Slicer sees
  header.resize(80, ' ');
  binary.replace(0, 80, header);
  write_bytes(dir / "nul.stl", binary);
  EXPECT_EQ(read_mesh(dir / "nul.stl").space, MeshSpace::Undeclared);
}

TEST(MeshSpace, AFileThatSaysBothIsRefusedByName) {
  const TempDir dir;
  const fs::path file = dir.path / "both.ply";
  std::string ply = slicer_file(MeshFormat::PlyAscii, tetrahedron(), "RAS");
  ply.insert(ply.find("element vertex"), "comment SPACE=LPS\n");
  write_bytes(file, ply);
  const std::string error = evar::test::error_message([&] { read_mesh(file); });
  EXPECT_THAT(error, HasSubstr(file.string()));
  EXPECT_THAT(error, HasSubstr("both SPACE=LPS and SPACE=RAS"));
}

// evarnode's binary header keeps not starting with "solid" (other readers would take it
// for ASCII) with the tag in it.
TEST(MeshSpace, TheBinaryStlHeaderStillDoesNotStartWithSolid) {
  const TempDir dir;
  const fs::path file = dir.path / "b.stl";
  write_mesh(file, tetrahedron(), MeshFormat::StlBinary, MeshSpace::Ras);
  const std::string bytes = read_bytes(file);
  EXPECT_NE(bytes.substr(0, 5), "solid");
  EXPECT_EQ(bytes.size(), 84u + 4u * 50u);
}
