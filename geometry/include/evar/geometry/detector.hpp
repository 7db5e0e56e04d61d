#pragma once
// The X-ray detector whose pixels the frames are, and the C-arm views on it: what a
// recorded session's frames and the live node's frames share, so recorded and live
// geometry cannot drift apart.
#include <Eigen/Core>

#include "evar/geometry/carm_projection.hpp"

namespace evar::geometry {

struct DetectorSpec {
  int cols = 0, rows = 0;  ///< pixels: 1 to 16384 each, at most 8192 x 8192 in all (image_header.hpp)
  double row_spacing_mm = 0.0, col_spacing_mm = 0.0;  ///< at the detector
};

/// The C-arm view of an angulation and distances on a detector.
CArmView view_of(const DetectorSpec& detector, double primary_deg, double secondary_deg, double sid_mm, double sod_mm);

/// CT → C-arm world at a table position: the registration holds at table position 0;
/// moving the table by t moves the patient by t in C-arm coordinates.
Eigen::Matrix4d patient_to_carm(const Eigen::Matrix4d& ct_to_carm, const Eigen::Vector3d& table_mm);

}  // namespace evar::geometry
