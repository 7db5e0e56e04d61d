#pragma once
// A C-arm view as the tests take one: SID 1200 mm, SOD 800 mm, a square detector of `px`
// pixels of `spacing_mm`, turned by the angles given.
#include "evar/geometry/carm_projection.hpp"

namespace evar::test {

inline geometry::CArmView carm_view(double primary_deg, double secondary_deg, int px, double spacing_mm) {
  geometry::CArmView v;
  v.primary_angle_deg = primary_deg;
  v.secondary_angle_deg = secondary_deg;
  v.source_to_detector_mm = 1200.0;
  v.source_to_isocenter_mm = 800.0;
  v.detector_cols = v.detector_rows = px;
  v.row_spacing_mm = v.col_spacing_mm = spacing_mm;
  return v;
}

}  // namespace evar::test
