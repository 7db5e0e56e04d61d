#include "evar/prepare/patient_axes.hpp"

#include <Eigen/LU>

#include <cctype>
#include <cmath>

#include "evar/base/input_error.hpp"

namespace evar::prepare {

PatientAxes parse_patient_axes(std::string_view code, std::string_view option) {
  const auto refuse = [&](const std::string& why) {
    throw base::InputError(std::string(option) + ": '" + std::string(code) + "' " + why +
                           "; give three letters saying which patient direction the file's x, y and z point to, "
                           "one of L/R, one of P/A and one of S/I (LPS: DICOM's and 3D Slicer's; RAS: older Slicer "
                           "models)");
  };
  if (code.size() != 3) refuse("is not three letters");
  PatientAxes out;
  bool used[3] = {false, false, false};
  for (int k = 0; k < 3; ++k) {
    const char c = static_cast<char>(std::toupper(static_cast<unsigned char>(code[static_cast<std::size_t>(k)])));
    out.code += c;
    int axis = -1;
    double sign = 1.0;
    switch (c) {
      case 'L': axis = 0; break;
      case 'R': axis = 0, sign = -1.0; break;
      case 'P': axis = 1; break;
      case 'A': axis = 1, sign = -1.0; break;
      case 'S': axis = 2; break;
      case 'I': axis = 2, sign = -1.0; break;
      default: refuse(std::string("has '") + c + "', which is no patient direction");
    }
    if (used[axis]) refuse("names the same patient axis twice");
    used[axis] = true;
    out.to_lps.col(k) = sign * Eigen::Vector3d::Unit(axis);
  }
  if (out.to_lps.determinant() < 0.0)
    refuse("mirrors the patient (a left-handed set of axes: left and right would swap); check the letter for x");
  return out;
}

std::string file_axis_name(const Eigen::Vector3d& direction) {
  Eigen::Index k = 0;
  direction.cwiseAbs().maxCoeff(&k);
  return std::string(direction[k] < 0.0 ? "-" : "+") + "xyz"[k];
}

}  // namespace evar::prepare
