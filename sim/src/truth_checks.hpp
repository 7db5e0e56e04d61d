#pragma once
// What both ground-truth models (device_distortion, conforming_distortion) need alike:
// where an iliac leaves the aorta, which vessel a wall point belongs to, and the check on
// the distorted meshes that they hold the device.
#include <Eigen/Core>
#include <cstddef>
#include <optional>
#include <vector>

#include "evar/geometry/polyline.hpp"
#include "evar/sim/device_distortion.hpp"
#include "evar/sim/example_scene.hpp"

namespace evar::sim::detail {

/// Number of leading iliac points inside the aorta's lumen (at least 1): the overlap that
/// moves with the bifurcation. `start_arc_on_aorta`: the aorta's arc length at the iliac's
/// first point.
std::size_t overlap_length(const ExampleVessel& iliac, const ExampleVessel& aorta, const std::vector<double>& aorta_arc,
                           double* start_arc_on_aorta);

/// Where the device crosses the plane through `centre` with normal `normal`: the crossing
/// nearest the centre, if any lies within `reach` mm of it.
std::optional<Eigen::Vector3d> device_crossing(const geometry::Polyline& device, const Eigen::Vector3d& centre,
                                               const Eigen::Vector3d& normal, double reach);

/// The vessel whose wall `x` sits on: |distance to its centerline - its radius| least.
std::size_t wall_vessel(const std::vector<ExampleVessel>& vessels, const Eigen::Vector3d& x);

struct DeviceOutside {
  std::size_t point = 0;      ///< device index (tip = 0)
  double gap_mm = 0.0;        ///< distance to the nearest wall
  std::size_t vessel = 0;     ///< the vessel of that wall
  Eigen::Vector3d wall_point = Eigen::Vector3d::Zero();
};

/// Device points neither inside one of the meshes (ray parity) nor within `slack_mm` of a
/// wall.
std::vector<DeviceOutside> device_outside(const std::vector<Eigen::Vector3d>& device,
                                          const std::vector<VesselDistortion>& vessels, double slack_mm);

/// Fills device_points_outside, worst_outside_mm and worst_outside_point from `outside`.
void record_outside(const std::vector<DeviceOutside>& outside, DeviceDistortion& out);

}  // namespace evar::sim::detail
