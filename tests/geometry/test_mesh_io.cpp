// Mesh files by extension (and OBJ), writing, and mesh validation: every kind of malformed
// input ending in an InputError that names the file.
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
  EXPECT_EQ(format_for_extension("d.VTP"), MeshFormat::Vtp);
  EXPECT_THROW(format_for_extension("e.off"), evar::base::InputError);
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
