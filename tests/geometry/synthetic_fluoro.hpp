#pragma once
// Rendered test frames of known wires (sim::render_fluoro) and the measures the
// segmentation and reconstruction tests assert on.
#include <cmath>
#include <vector>

#include "evar/geometry/carm_projection.hpp"
#include "evar/sim/curve_metrics.hpp"
#include "evar/sim/fluoro_render.hpp"

namespace evar::test {

/// A 0.3 mm, 1024 x 1024 detector (the accuracy case), SID 1200, SOD 800.
inline geometry::CArmView detector_view(double primary_deg, double secondary_deg, int size_px = 1024, double spacing_mm = 0.3) {
  geometry::CArmView v;
  v.primary_angle_deg = primary_deg;
  v.secondary_angle_deg = secondary_deg;
  v.source_to_detector_mm = 1200;
  v.source_to_isocenter_mm = 800;
  v.detector_cols = size_px;
  v.detector_rows = size_px;
  v.row_spacing_mm = v.col_spacing_mm = spacing_mm;
  return v;
}

using sim::iliac_guidewire;

/// Expected shadow width (px) of a wire of `diameter_mm` at the isocenter.
inline double shadow_width_px(const geometry::CArmView& v) { return geometry::device_shadow_width_px(v, 0.89); }

using sim::CurveMatch;
inline CurveMatch match(const std::vector<Eigen::Vector2d>& found, const std::vector<Eigen::Vector2d>& truth,
                        const cv::Rect2d& region) {
  return sim::match_curve(found, truth, region);
}

}  // namespace evar::test
