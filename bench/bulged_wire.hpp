#pragma once
// The wire the scene benchmarks deform with: down the aortic centerline (its last 20 points
// left out, toward the crotch), then the right iliac's, bulged 8 mm (about two of its
// radii) to the patient's right in its middle, as a stiff wire straightens the iliac.
#include <cmath>

#include "evar/geometry/polyline.hpp"
#include "evar/geometry/scene.hpp"

namespace evar::bench {

inline geometry::Polyline bulged_wire(const geometry::Scene& scene) {
  const auto& aorta = scene.vessels[0].centerline;
  const auto& right = scene.vessels[1].centerline;
  geometry::Polyline wire;
  for (std::size_t i = 0; i + 20 < aorta.size(); ++i) wire.push_back(aorta[i]);
  const auto arc = geometry::arc_lengths(right);
  for (std::size_t i = 0; i < right.size(); ++i)
    wire.push_back(right[i] + Eigen::Vector3d(-8.0 * std::sin(M_PI * arc[i] / arc.back()), 0, 0));
  return wire;
}

}  // namespace evar::bench
