#pragma once
// Which patient direction each axis of a file points to, as a three-letter code (one of
// L/R, one of P/A, one of S/I, in the order of the file's x, y and z): "LPS" is what
// evarnode, DICOM and 3D Slicer's files use, "RAS" Slicer's old model files; a surface
// segmented in an image's own axes has some other code, which only its user can say (the
// anatomy fixes head to foot, not left from right).
#include <Eigen/Core>
#include <string>
#include <string_view>

namespace evar::prepare {

struct PatientAxes {
  std::string code;                                      ///< e.g. "LPS"
  Eigen::Matrix3d to_lps = Eigen::Matrix3d::Identity();  ///< file coordinates -> LPS (a rotation)
};

/// Parses a code (case-insensitive). base::InputError naming `option` for anything that is
/// not three letters naming each of the three patient axes once, or that mirrors the
/// patient (a left-handed code such as "LPI": left and right would swap).
PatientAxes parse_patient_axes(std::string_view code, std::string_view option = "--axes");

/// The file axis a unit direction (file coordinates) runs along, as people write it:
/// "+y", "-z"; the largest component's.
std::string file_axis_name(const Eigen::Vector3d& direction);

}  // namespace evar::prepare
