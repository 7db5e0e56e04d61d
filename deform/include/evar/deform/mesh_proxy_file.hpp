#pragma once
// A vessel's proxy (mesh_proxy.hpp) kept beside its mesh, so the remeshing is paid once per
// scene (by `evarnode scene`) and not at every load: the proxy's mesh, the fine vertices'
// bindings, the edge it was made for and a fingerprint of the fine mesh it belongs to.
//
// File layout (little-endian; docs/FORMATS.md, "Proxy files"): the 16 bytes
// "evarnode-proxy2\n"; edge_mm (f64, asked); the edge it was remeshed to (f64: edge_mm, or
// finer where that was refused); the fine mesh's vertex and face counts (u64 each) and
// its fingerprint (u64); the proxy's vertex and face counts (u64 each); its largest offset
// (f64); its vertices (3 f64 each) and faces (3 i32 each); per fine vertex its binding
// (face i32, barycentric weights 3 f64, offset in the face's frame 3 f64).
#include <cstdint>
#include <filesystem>

#include "evar/deform/mesh_proxy.hpp"
#include "evar/geometry/triangle_mesh.hpp"

namespace evar::deform {

/// FNV-1a (64 bit) over a mesh's vertex coordinates and faces as stored: the same mesh
/// read from the same file gives the same value, any edit another.
std::uint64_t mesh_fingerprint(const geometry::TriangleMesh& mesh);

/// Writes `proxy`, made from `fine` with edges of `edge_mm`, atomically to `file`.
void write_mesh_proxy(const std::filesystem::path& file, const MeshProxy& proxy, const geometry::TriangleMesh& fine,
                      double edge_mm);

/// Reads the proxy in `file` for `fine` and `edge_mm`. std::runtime_error, naming the file
/// and what is wrong, when it cannot be read, is damaged, or was made for another mesh or
/// edge (the caller then makes the proxy anew).
MeshProxy read_mesh_proxy(const std::filesystem::path& file, const geometry::TriangleMesh& fine, double edge_mm);

}  // namespace evar::deform
