#pragma once
// Private to evar_geometry: VTK XML PolyData (.vtp) read and written with VTK's own
// vtkXMLPolyDataReader / vtkXMLPolyDataWriter, the library VMTK, 3D Slicer and PLUS use,
// with VTK's errors turned into InputError naming the file (VTK itself only prints them
// and returns what it has).
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>

#include "evar/geometry/mesh_io.hpp"

class vtkPolyData;

namespace evar::geometry::detail {

struct VtkPolyDataDeleter {
  void operator()(vtkPolyData* p) const;
};
using PolyDataHandle = std::unique_ptr<vtkPolyData, VtkPolyDataDeleter>;

/// The file's polydata (`bytes` is its whole content; `path` names it in errors).
PolyDataHandle parse_vtp(const std::filesystem::path& path, std::string_view bytes);

/// The coordinate system its field data declares, as 3D Slicer writes it: a string array
/// "SPACE" holding "LPS" or "RAS" (InputError for another value).
MeshSpace vtp_declared_space(const std::filesystem::path& path, vtkPolyData& data);

/// A .vtp's triangles (polygons fan-triangulated, strips unrolled), in the file's
/// coordinates, with the space it declares.
LoadedMesh read_vtp(const std::filesystem::path& path, std::string_view bytes);

/// Writes the triangles as VTK XML PolyData (Float64 points, appended zlib-compressed data,
/// as Slicer writes compressed models), declaring `space_tag`'s system in the field data.
void write_vtp(const std::filesystem::path& path, const TriangleMesh& mesh, MeshSpace space);

}  // namespace evar::geometry::detail
