#include "evar/geometry/detector.hpp"

namespace evar::geometry {

CArmView view_of(const DetectorSpec& detector, double primary_deg, double secondary_deg, double sid_mm, double sod_mm) {
  CArmView v;
  v.primary_angle_deg = primary_deg;
  v.secondary_angle_deg = secondary_deg;
  v.source_to_detector_mm = sid_mm;
  v.source_to_isocenter_mm = sod_mm;
  v.detector_cols = detector.cols;
  v.detector_rows = detector.rows;
  v.row_spacing_mm = detector.row_spacing_mm;
  v.col_spacing_mm = detector.col_spacing_mm;
  return v;
}

Eigen::Matrix4d patient_to_carm(const Eigen::Matrix4d& ct_to_carm, const Eigen::Vector3d& table_mm) {
  Eigen::Matrix4d T = ct_to_carm;
  T.topRightCorner<3, 1>() += table_mm;
  return T;
}

}  // namespace evar::geometry
