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

inline geometry::CArmView read_view(const std::filesystem::path& path) {
  base::check_input_file(path, base::kDicomLimit);  // before opening: a FIFO would block
  return is_dicom_file(path) ? geometry::read_xa_dicom(path).view : geometry::read_view_geometry(path);
}

/// The view geometry file's video mapping (none for DICOM: its frames are the detector's).
inline std::optional<geometry::VideoMapping> read_video_mapping_of_view(const std::filesystem::path& path) {
  return is_dicom_file(path) ? std::nullopt : geometry::read_view_video_mapping(path);
}

}  // namespace evar::app
