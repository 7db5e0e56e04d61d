// Mesh file dispatch by extension, plus the file helpers the format readers share.
#include "evar/geometry/mesh_io.hpp"

#include <algorithm>
#include <cctype>
#include <stdexcept>

#include "evar/base/input_file.hpp"
#include "mesh_formats.hpp"
#include "vtk_xml.hpp"

namespace evar::geometry {

namespace detail {

std::string quoted(std::string_view token) {
  std::string out = "'";
  for (std::size_t i = 0; i < token.size() && i < 24; ++i) {
    const auto c = static_cast<unsigned char>(token[i]);
    out += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
  }
  if (token.size() > 24) out += "...";
  return out + "'";
}

void fail(const std::filesystem::path& path, const std::string& what) {
  throw base::InputError(path.string() + ": " + what);
}

void check_indices_for_writing(const TriangleMesh& mesh, const std::filesystem::path& path) {
  const auto n = mesh.V.rows();
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int i = mesh.F(f, k);
      if (i < 0 || i >= n) {
        throw std::invalid_argument(path.string() + ": cannot write: face " + std::to_string(f) +
                                    " has vertex index " + std::to_string(i) +
                                    " but the mesh has " + std::to_string(n) + " vertices");
      }
    }
  }
}

}  // namespace detail

namespace {

std::string lower_extension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

}  // namespace

LoadedMesh read_mesh(const std::filesystem::path& path) {
  const std::string ext = lower_extension(path);
  if (ext != ".stl" && ext != ".ply" && ext != ".obj" && ext != ".vtk" && ext != ".vtp") {
    detail::fail(path, "unknown mesh extension '" + path.extension().string() +
                           "' (expected .stl, .ply, .obj, .vtk or .vtp)");
  }
  const std::string bytes = base::read_input_file(path, base::kMeshLimit);
  if (ext == ".vtp") {
    LoadedMesh loaded = detail::read_vtp(path, bytes);
    if (loaded.space == MeshSpace::Ras) detail::flip_lps_ras(loaded.mesh);
    return loaded;
  }
  LoadedMesh loaded = ext == ".stl"   ? detail::read_stl(path, bytes)
                      : ext == ".ply" ? detail::read_ply(path, bytes)
                      : ext == ".vtk" ? detail::read_vtk(path, bytes)
                                      : LoadedMesh{detail::read_obj(path, bytes), MeshFormat::Obj};
  loaded.space = detail::declared_space(path, bytes, loaded.format);
  if (loaded.space == MeshSpace::Ras) detail::flip_lps_ras(loaded.mesh);
  return loaded;
}

void write_mesh(const std::filesystem::path& path, const TriangleMesh& mesh, MeshFormat format, MeshSpace space) {
  TriangleMesh in_ras;
  if (space == MeshSpace::Ras) {
    in_ras = mesh;
    detail::flip_lps_ras(in_ras);
  }
  const TriangleMesh& out = space == MeshSpace::Ras ? in_ras : mesh;
  const std::string_view tag = detail::space_tag(space);
  switch (format) {
    case MeshFormat::StlBinary: return detail::write_stl(path, out, true, tag);
    case MeshFormat::StlAscii: return detail::write_stl(path, out, false, tag);
    case MeshFormat::PlyBinary: return detail::write_ply(path, out, true, tag);
    case MeshFormat::PlyAscii: return detail::write_ply(path, out, false, tag);
    case MeshFormat::Obj: return detail::write_obj(path, out, tag);
    case MeshFormat::VtkBinary: return detail::write_vtk(path, out, true, tag);
    case MeshFormat::VtkAscii: return detail::write_vtk(path, out, false, tag);
    case MeshFormat::Vtp: return detail::write_vtp(path, out, space);
  }
  throw std::invalid_argument(path.string() + ": unknown mesh format");
}

const char* extension_for(MeshFormat format) {
  switch (format) {
    case MeshFormat::StlBinary:
    case MeshFormat::StlAscii: return ".stl";
    case MeshFormat::PlyAscii:
    case MeshFormat::PlyBinary: return ".ply";
    case MeshFormat::Obj: return ".obj";
    case MeshFormat::VtkAscii:
    case MeshFormat::VtkBinary: return ".vtk";
    case MeshFormat::Vtp: return ".vtp";
  }
  throw std::invalid_argument("extension_for: unknown mesh format");
}

MeshFormat format_for_extension(const std::filesystem::path& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".stl") return MeshFormat::StlBinary;
  if (ext == ".ply") return MeshFormat::PlyBinary;
  if (ext == ".obj") return MeshFormat::Obj;
  if (ext == ".vtk") return MeshFormat::VtkBinary;
  if (ext == ".vtp") return MeshFormat::Vtp;
  detail::fail(path, "cannot choose a mesh format for extension '" + path.extension().string() +
                         "' (expected .stl, .ply, .obj, .vtk or .vtp)");
}

}  // namespace evar::geometry
