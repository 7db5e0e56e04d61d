#include "evar/node/frame_view.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace evar::node {

FrameView frame_view(const geometry::DetectorSpec& detector, const Eigen::Matrix4d& registration,
                     const acquisition::CArmState& state) {
  return frame_view(geometry::view_of(detector, state.primary_deg, state.secondary_deg, state.sid_mm, state.sod_mm),
                    registration, state);
}

FrameView frame_view(const geometry::CArmView& view, const Eigen::Matrix4d& registration,
                     const acquisition::CArmState& state) {
  FrameView f;
  f.view = view;
  f.ct_to_carm = geometry::patient_to_carm(registration, Eigen::Vector3d(state.table_mm[0], state.table_mm[1], state.table_mm[2]));
  f.P_ct = geometry::registered(geometry::projection_matrix(f.view), f.ct_to_carm);
  return f;
}

std::string angulation_text(double primary_deg, double secondary_deg) {
  char b[64];
  std::snprintf(b, sizeof b, "%s %.0f  %s %.0f", primary_deg >= 0 ? "LAO" : "RAO", std::abs(primary_deg),
                secondary_deg >= 0 ? "CRA" : "CAU", std::abs(secondary_deg));
  return b;
}

double mm_at_isocenter_per_px(const geometry::CArmView& view) {
  return std::min(view.row_spacing_mm, view.col_spacing_mm) * view.source_to_isocenter_mm /
         view.source_to_detector_mm;
}

}  // namespace evar::node
