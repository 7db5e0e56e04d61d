#pragma once
// Reading and writing STL (binary and ASCII), PLY (ASCII and binary) and OBJ meshes.
// Vertex order and topology are kept exactly for PLY and OBJ; STL, which stores a
// triangle soup, is welded (bit-identical positions become one vertex, in order of
// first appearance) so that the mesh has connectivity; triangles whose corners weld
// together (zero-area slivers) are dropped.
#include <filesystem>

#include "evar/geometry/triangle_mesh.hpp"

namespace evar::geometry {

enum class MeshFormat { StlBinary, StlAscii, PlyAscii, PlyBinary, Obj };

struct LoadedMesh {
  TriangleMesh mesh;
  MeshFormat format = MeshFormat::StlBinary;  ///< what the file was, so output can be written the same way
};

/// Reads a mesh, choosing the reader by extension (.stl, .ply, .obj; case-insensitive)
/// and, for STL and PLY, by content. Throws InputError naming the file and the problem
/// (missing, unreadable, truncated, malformed line/byte) for anything it cannot read.
LoadedMesh read_mesh(const std::filesystem::path& path);

/// Writes `mesh` to `path` in `format`. Throws std::runtime_error if the file cannot be
/// written and std::invalid_argument for face indices out of range. Faces may reference only some of the vertices: all vertices are written (PLY,
/// OBJ) so vertex indices stay valid.
void write_mesh(const std::filesystem::path& path, const TriangleMesh& mesh, MeshFormat format);

/// The format to write for a path given its extension (STL -> binary, PLY -> binary);
/// InputError for an extension that is none of .stl, .ply, .obj.
MeshFormat format_for_extension(const std::filesystem::path& path);

}  // namespace evar::geometry
