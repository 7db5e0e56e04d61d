#pragma once
// A view's geometry from the command line: a view geometry JSON file, or a DICOM XA /
// Enhanced XA file (recognized by its "DICM" preamble, whatever its name).
#include <filesystem>
#include <fstream>

#include "evar/geometry/carm_projection.hpp"
#include "evar/base/input_file.hpp"
#include "evar/geometry/xa_dicom.hpp"

namespace evar::app {

inline bool is_dicom_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[132] = {};
  return in.read(magic, sizeof magic) && std::string(magic + 128, 4) == "DICM";
}

/// The view and, for a view geometry JSON file, its video mapping (a DICOM file's frames
/// are the detector's).
inline geometry::ViewGeometryFile read_view_file(const std::filesystem::path& path) {
  base::check_input_file(path, base::kDicomLimit);  // before opening: a FIFO would block
  if (is_dicom_file(path)) return {geometry::read_xa_dicom(path).view, std::nullopt};
  return geometry::read_view_geometry_file(path);
}

inline geometry::CArmView read_view(const std::filesystem::path& path) { return read_view_file(path).view; }

}  // namespace evar::app
