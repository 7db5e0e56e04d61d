#pragma once
// The shadow of thin wires (guidewires, catheters) on the detector: per pixel the mean of
// exp(−μ·chord) over 4x4 subsamples, the chord being the ray's path through a cylinder of
// the wire's diameter (oblique rays included). Shared by the fluoroscopy renderers.
#include <vector>

#include <opencv2/core.hpp>

#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/polyline.hpp"

namespace evar::sim {

/// CV_64F transmittance (1 = no wire) for wires in world mm seen through P; `truth`, when
/// given, receives each wire's projected centreline (px), in order.
cv::Mat wire_transmittance(const geometry::ProjectionMatrix& P, const geometry::CArmView& view,
                           const std::vector<geometry::Polyline>& wires, double diameter_mm, double mu_per_mm,
                           std::vector<std::vector<Eigen::Vector2d>>* truth);

}  // namespace evar::sim
