#pragma once
// What both ground-truth models (device_distortion, conforming_distortion) need alike:
// where an iliac leaves the aorta, which vessel a wall point belongs to, and the check on
// the distorted meshes that they hold the device.
#include <Eigen/Core>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "evar/geometry/polyline.hpp"
#include "evar/sim/device_distortion.hpp"
#include "evar/sim/example_scene.hpp"

namespace evar::sim::detail {

/// Which vessel does what, as both models read a scene: the aorta, the iliacs, the carrier
/// (the iliac whose distal end is nearest the device's access end), each iliac's overlap
/// with the aorta (overlap_length; 0 for the aorta) and the hub's arc on the aorta (the
/// highest iliac start). Throws std::invalid_argument, prefixed by `who`, for a device of
/// < 2 points, a vessel of < 3 centerline points or without a radius each, or a scene
/// without an aorta and an iliac.
struct VesselRoles {
  std::size_t aorta = 0, carrier = 0;
  std::vector<std::size_t> iliacs;
  std::vector<std::size_t> overlap;  ///< per scene vessel
  double hub_arc_mm = 0.0;
};
VesselRoles vessel_roles(const ExampleScene& scene, const std::string& who);

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
