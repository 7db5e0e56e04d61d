#pragma once
// A frame's imaging geometry as the node uses it: the C-arm view on the detector, the
// CT-to-C-arm transform at the table position of the moment, and the projection of CT
// points (LPS mm) to the frame's pixels.
#include <Eigen/Core>
#include <string>

#include "evar/acquisition/carm_geometry_source.hpp"
#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/detector.hpp"

namespace evar::node {

struct FrameView {
  geometry::CArmView view;
  Eigen::Matrix4d ct_to_carm = Eigen::Matrix4d::Identity();
  geometry::ProjectionMatrix P_ct = geometry::ProjectionMatrix::Zero();  ///< CT LPS mm → pixels
};

/// The view of a C-arm state on `detector`, with the registration (which holds at table
/// position 0) moved by the table: CT → C-arm = translate(table) · registration.
/// std::invalid_argument for impossible geometry (SOD >= SID, ...).
FrameView frame_view(const geometry::DetectorSpec& detector, const Eigen::Matrix4d& registration,
                     const acquisition::CArmState& state);
/// The same for a view made otherwise (a zoom mode's: geometry::zoom_view); the state gives
/// the table position.
FrameView frame_view(const geometry::CArmView& view, const Eigen::Matrix4d& registration,
                     const acquisition::CArmState& state);

/// "LAO 35  CAU 15": the angulation as interventionalists say it (whole degrees).
std::string angulation_text(double primary_deg, double secondary_deg);

/// Pixel distances at the detector as millimetres at the isocenter: px · spacing · SOD/SID
/// (the finer spacing).
double mm_at_isocenter_per_px(const geometry::CArmView& view);

}  // namespace evar::node
