// VTK XML PolyData (.vtp) through VTK: round trips, 3D Slicer's SPACE field, VMTK's own
// files (surface and centerlines), and bad files named.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <tuple>

#include "evar/base/input_error.hpp"
#include "evar/geometry/centerline_file.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "support/error_message.hpp"
#include "support/shared_data.hpp"
#include "support/temp_dir.hpp"

namespace fs = std::filesystem;
using namespace evar;

namespace {

geometry::TriangleMesh tetrahedron_with_a_spare_vertex() {
  geometry::TriangleMesh m;
  m.V.resize(5, 3);
  m.V << 0.1, 0.2, 0.3, 10.0 / 3.0, 0, 0, 0, 1e-9, 0, 0, 0, 123456.789012345, 7, 7, 7;
  m.F.resize(4, 3);
  m.F << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  return m;
}

void write_text(const fs::path& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

std::string error_of(const fs::path& path) {
  return test::error_message([&] { geometry::read_mesh(path); }, "");
}

}  // namespace

TEST(VtpIo, ARoundTripKeepsEveryDoubleTheVertexOrderAndTheFaces) {
  const test::TempDir dir;
  const auto mesh = tetrahedron_with_a_spare_vertex();
  for (const auto space : {geometry::MeshSpace::Lps, geometry::MeshSpace::Ras}) {
    const auto path = dir.path / "model.vtp";
    geometry::write_mesh(path, mesh, geometry::format_for_extension(path), space);
    const auto back = geometry::read_mesh(path);
    EXPECT_EQ(back.format, geometry::MeshFormat::Vtp);
    EXPECT_EQ(back.space, space);
    EXPECT_EQ(back.mesh.V, mesh.V);  // exactly: Float64 points, and RAS flipped back
    EXPECT_EQ(back.mesh.F, mesh.F);
  }
}

// What 3D Slicer writes (a polygon, a triangle strip, the SPACE field) as VTK's own writer
// puts it in ASCII, read as triangles facing one way.
TEST(VtpIo, PolygonsAndStripsAreTriangulatedAndSlicersSpaceFieldIsRead) {
  const test::TempDir dir;
  const auto path = dir.path / "slicer.vtp";
  write_text(path, R"(<?xml version="1.0"?>
<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" header_type="UInt64">
  <PolyData>
    <FieldData>
      <Array type="String" Name="SPACE" NumberOfTuples="1" format="ascii">
        82 65 83 0
      </Array>
    </FieldData>
    <Piece NumberOfPoints="6" NumberOfVerts="0" NumberOfLines="0" NumberOfStrips="1" NumberOfPolys="1">
      <Points>
        <DataArray type="Float32" NumberOfComponents="3" format="ascii">
          0 0 0  1 0 0  1 1 0  0 1 0  2 0 0  2 1 0
        </DataArray>
      </Points>
      <Strips>
        <DataArray type="Int64" Name="connectivity" format="ascii">1 4 2 5</DataArray>
        <DataArray type="Int64" Name="offsets" format="ascii">4</DataArray>
      </Strips>
      <Polys>
        <DataArray type="Int64" Name="connectivity" format="ascii">0 1 2 3</DataArray>
        <DataArray type="Int64" Name="offsets" format="ascii">4</DataArray>
      </Polys>
    </Piece>
  </PolyData>
</VTKFile>
)");
  const auto loaded = geometry::read_mesh(path);
  EXPECT_EQ(loaded.space, geometry::MeshSpace::Ras);
  ASSERT_EQ(loaded.mesh.V.rows(), 6);
  EXPECT_EQ(loaded.mesh.V(1, 0), -1.0);  // RAS read into LPS: x and y negated
  ASSERT_EQ(loaded.mesh.F.rows(), 4);
  // Polygons first (fan), then the strip's two triangles, the second turned.
  EXPECT_EQ(loaded.mesh.F.row(0), Eigen::RowVector3i(0, 1, 2));
  EXPECT_EQ(loaded.mesh.F.row(1), Eigen::RowVector3i(0, 2, 3));
  EXPECT_EQ(loaded.mesh.F.row(2), Eigen::RowVector3i(1, 4, 2));
  EXPECT_EQ(loaded.mesh.F.row(3), Eigen::RowVector3i(4, 5, 2));
}

TEST(VtpIo, BadFilesAreRefusedNamingTheFileAndTheProblem) {
  const test::TempDir dir;
  const auto not_xml = dir.path / "not_xml.vtp";
  write_text(not_xml, "solid x\nendsolid x\n");
  EXPECT_NE(error_of(not_xml).find("not_xml.vtp: is not a VTK XML file"), std::string::npos) << error_of(not_xml);

  // A real file cut in half.
  const auto whole = dir.path / "whole.vtp";
  geometry::write_mesh(whole, tetrahedron_with_a_spare_vertex(), geometry::MeshFormat::Vtp);
  std::ifstream in(whole, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto cut = dir.path / "cut.vtp";
  write_text(cut, bytes.substr(0, bytes.size() / 2));
  const std::string cut_error = error_of(cut);
  EXPECT_NE(cut_error.find("cut.vtp: VTK's XML reader: "), std::string::npos) << cut_error;

  const auto wrong_space = dir.path / "space.vtp";
  std::string text = bytes;
  write_text(wrong_space, R"(<?xml version="1.0"?>
<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" header_type="UInt64">
  <PolyData>
    <FieldData>
      <Array type="String" Name="SPACE" NumberOfTuples="1" format="ascii">88 89 90 0</Array>
    </FieldData>
    <Piece NumberOfPoints="3" NumberOfPolys="1">
      <Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">0 0 0 1 0 0 0 1 0</DataArray></Points>
      <Polys>
        <DataArray type="Int64" Name="connectivity" format="ascii">0 1 2</DataArray>
        <DataArray type="Int64" Name="offsets" format="ascii">3</DataArray>
      </Polys>
    </Piece>
  </PolyData>
</VTKFile>
)");
  EXPECT_NE(error_of(wrong_space).find("space.vtp: field data SPACE: is 'XYZ'; expected LPS or RAS"), std::string::npos)
      << error_of(wrong_space);
}

// VMTK's own surface, as .vtp and as .stl: the same surface, every vertex and triangle.
TEST(VtpIo, VmtksSurfaceReadsAsTheSameMeshFromVtpAndStl) {
  EVAR_VMTK_DATA_OR_SKIP(dir);
  const auto vtp = geometry::read_mesh(dir / "aorta-surface.vtp");
  const auto stl = geometry::read_mesh(dir / "aorta-surface.stl");
  EXPECT_EQ(vtp.format, geometry::MeshFormat::Vtp);
  EXPECT_EQ(vtp.space, geometry::MeshSpace::Undeclared);
  EXPECT_EQ(vtp.mesh.V.rows(), 6468);
  EXPECT_EQ(vtp.mesh.F.rows(), 12932);
  EXPECT_EQ(stl.mesh.F.rows(), 12932);
  // The same triangles as sets of corner positions (STL is welded, so its vertex order differs).
  const auto corners = [](const geometry::TriangleMesh& m) {
    std::multiset<std::tuple<float, float, float>> out;
    for (Eigen::Index f = 0; f < m.F.rows(); ++f)
      for (int k = 0; k < 3; ++k)
        out.emplace(static_cast<float>(m.V(m.F(f, k), 0)), static_cast<float>(m.V(m.F(f, k), 1)),
                    static_cast<float>(m.V(m.F(f, k), 2)));
    return out;
  };
  EXPECT_TRUE(corners(vtp.mesh) == corners(stl.mesh));
  EXPECT_NO_THROW(geometry::validate_mesh(vtp.mesh, "aorta-surface.vtp"));
  // A centerline file given as a mesh is named for what it is.
  const std::string err = error_of(dir / "aorta-centerline.vtp");
  EXPECT_NE(err.find("it looks like a centerline file"), std::string::npos) << err;
}

TEST(VtpIo, VmtksCenterlinesReadWithTheirRadiiAndBranchIds) {
  EVAR_VMTK_DATA_OR_SKIP(dir);
  const auto paths = geometry::read_centerline_file(dir / "aorta-centerline.vtp");
  ASSERT_EQ(paths.curves.size(), 2u);  // inlet to each outlet
  for (const auto& c : paths.curves) {
    ASSERT_GT(c.points.size(), 50u);
    ASSERT_EQ(c.radius_mm.size(), c.points.size());
    EXPECT_GT(*std::min_element(c.radius_mm.begin(), c.radius_mm.end()), 1.0);
    EXPECT_LT(*std::max_element(c.radius_mm.begin(), c.radius_mm.end()), 15.0);
  }
  // Both paths start at the same inlet.
  EXPECT_LT((paths.curves[0].points.front() - paths.curves[1].points.front()).norm(), 1e-6);
  const auto branches = geometry::read_centerline_file(dir / "aorta-centerline-branches.vtp");
  ASSERT_GE(branches.curves.size(), 3u);
  std::set<long long> groups;
  for (const auto& c : branches.curves) {
    for (const char* name : {"CenterlineIds", "GroupIds", "TractIds", "Blanking"})
      EXPECT_TRUE(c.cell_values.count(name)) << name;
    groups.insert(c.cell_values.at("GroupIds"));
  }
  EXPECT_GE(groups.size(), 3u);  // the aorta, the bifurcation, each iliac
  // A surface given as centerlines is refused by name.
  try {
    geometry::read_centerline_file(dir / "aorta-surface.vtp");
    FAIL() << "a surface read as centerlines";
  } catch (const base::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("holds no lines"), std::string::npos) << e.what();
  }
}
