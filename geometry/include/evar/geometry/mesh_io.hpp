#pragma once
// Reading and writing STL (binary and ASCII), PLY (ASCII and binary), OBJ, VTK legacy
// polydata (.vtk, ASCII and binary: 3D Slicer's default model format) and VTK XML PolyData
// (.vtp: VMTK's and many Slicer workflows' format, through VTK) meshes.
// Vertex order and topology are kept exactly for PLY, OBJ, VTK and VTP; STL, which stores a
// triangle soup, is welded (bit-identical positions become one vertex, in order of
// first appearance) so that the mesh has connectivity; triangles whose corners weld
// together (zero-area slivers) are dropped.
//
// Coordinates are patient LPS in memory. A file may say which system its coordinates are
// in the way 3D Slicer writes it ("SPACE=LPS" or "SPACE=RAS" in the binary STL header or
// the ASCII STL's solid line, a PLY comment, the OBJ's leading comment, the VTK title, the
// VTP's "SPACE" field data string); a file that says
// RAS is turned into LPS on reading (x and y negated) and written back as RAS.
#include <filesystem>

#include "evar/geometry/triangle_mesh.hpp"

namespace evar::geometry {

enum class MeshFormat { StlBinary, StlAscii, PlyAscii, PlyBinary, Obj, VtkAscii, VtkBinary, Vtp };

/// The patient coordinate system a mesh file declares. Undeclared is read as LPS, as 3D
/// Slicer has read and written mesh files since version 4.11.
enum class MeshSpace { Undeclared, Lps, Ras };

struct LoadedMesh {
  TriangleMesh mesh;  ///< in LPS, whatever the file declared
  MeshFormat format = MeshFormat::StlBinary;  ///< what the file was, so output can be written the same way
  MeshSpace space = MeshSpace::Undeclared;    ///< what the file declared, so output can declare the same
};

/// Reads a mesh, choosing the reader by extension (.stl, .ply, .obj, .vtk, .vtp; case-insensitive)
/// and, for STL, PLY and VTK, by content. Throws InputError naming the file and the problem
/// (missing, unreadable, truncated, malformed line/byte, both SPACE=LPS and SPACE=RAS
/// declared) for anything it cannot read.
LoadedMesh read_mesh(const std::filesystem::path& path);

/// Writes `mesh` (LPS) to `path` in `format`, declaring `space` in the file: Ras negates x
/// and y and says SPACE=RAS; Lps and Undeclared write LPS and say SPACE=LPS. Throws
/// std::runtime_error if the file cannot be written and std::invalid_argument for face
/// indices out of range. Faces may reference only some of the vertices: all vertices are
/// written (PLY, OBJ) so vertex indices stay valid.
void write_mesh(const std::filesystem::path& path, const TriangleMesh& mesh, MeshFormat format,
                MeshSpace space = MeshSpace::Lps);

/// The format to write for a path given its extension (STL, PLY and VTK -> binary);
/// InputError for an extension that is none of .stl, .ply, .obj, .vtk, .vtp.
MeshFormat format_for_extension(const std::filesystem::path& path);

/// The extension a file of `format` is written with (".stl", ".ply", ".obj", ".vtk", ".vtp").
const char* extension_for(MeshFormat format);

}  // namespace evar::geometry
