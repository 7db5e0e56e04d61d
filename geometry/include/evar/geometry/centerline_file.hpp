#pragma once
// Centerlines as VMTK writes them: VTK XML PolyData (.vtp) whose lines are the centerline
// paths (vmtkcenterlines: one per outlet, from the inlet, sharing their common part) or
// their branches (vmtkbranchextractor: one cell per branch piece, with CenterlineIds,
// GroupIds, TractIds and Blanking cell arrays), each point carrying its
// MaximumInscribedSphereRadius.
#include <Eigen/Core>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/polyline.hpp"

namespace evar::geometry {

struct CenterlineCurve {
  Polyline points;                ///< LPS mm, in the file's order
  std::vector<double> radius_mm;  ///< the lumen radius per point; empty when the file has none
  /// The cell's integer arrays, by name (VMTK's CenterlineIds, GroupIds, TractIds,
  /// Blanking; whatever else the file carries).
  std::map<std::string, long long> cell_values;
};

struct CenterlineFile {
  std::vector<CenterlineCurve> curves;  ///< one per line cell, in the file's order
  MeshSpace space = MeshSpace::Undeclared;
};

/// Name of the point array VMTK stores the lumen radius in.
inline constexpr const char* kVmtkRadiusArray = "MaximumInscribedSphereRadius";

/// Reads a .vtp centerline file. Coordinates are turned into LPS when its field data says
/// SPACE=RAS. InputError naming the file for anything unreadable, a file without lines, a
/// radius array that is not one number per point, or a non-finite or negative radius.
CenterlineFile read_centerline_file(const std::filesystem::path& path);

}  // namespace evar::geometry
