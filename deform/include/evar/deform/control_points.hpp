#pragma once
// Control point selection (paper 2.2): rays are cast from the vessel centerline toward the
// 3D device; where a ray hits the wall before reaching the device, the device lies outside
// the vessel there and the hit point h becomes a handle moved by
//   s = d − h + Δd (d − h) / |d − h|                                          (eq. 6)
// (d the device point, Δd the device thickness), so the wall ends up Δd beyond the device.
// No anchors: where the device is inside, the wall gets no constraint. With pair_in_order
// each section's ray goes to its partner along the device (ordered_pairing.hpp) rather than
// to its nearest device point.
#include <Eigen/Core>
#include <functional>
#include <map>
#include <optional>
#include <vector>

#include "evar/deform/skeleton.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/ray_caster.hpp"
#include "evar/geometry/triangle_mesh.hpp"

namespace evar::deform {

struct ControlPointOptions {
  double device_thickness_mm = 0.9;  ///< Δd
  /// Minimum distance between two handles' hit points; 0 = 1.5 x the mesh's median edge
  /// length. This is the resampling that keeps handles evenly spaced in tortuous vessels.
  double spacing_mm = 0.0;
  double sample_step_mm = 0.5;       ///< sampling of centerline and device for the rays
  /// A device point belongs to this vessel only if it is within this many local radii of
  /// the centerline and projects inside the centerline's extent.
  double reach_radii = 3.0;
  /// Pair sections and device points in the order both run in (ordered_pairing.hpp)
  /// instead of each with its nearest: for a vessel the device runs through.
  bool pair_in_order = false;
};

struct Handle {
  Eigen::Vector3d hit;           ///< h, on the wall (mm)
  int face;                      ///< triangle holding h
  Eigen::Vector3d barycentric;   ///< of h in that triangle
  Eigen::Vector3d device_point;  ///< d
  Eigen::Vector3d shift;         ///< s (mm)
  double arc_mm;                 ///< where along the centerline the ray started
};

/// Device points (resampled) that belong to this vessel, as described in the options.
std::vector<Eigen::Vector3d> device_points_in_vessel(const geometry::Polyline& centerline, const RadiusProfile& radius,
                                                     const geometry::Polyline& device, const ControlPointOptions& options);

/// True for a point inside the lumen of another vessel of the scene.
using LumenTest = std::function<bool(const Eigen::Vector3d&)>;

/// Selects the handles: rays from centerline samples to their nearest device point and from
/// each device sample's foot on the centerline to it, then thinned to `spacing_mm` keeping
/// the deepest penetrations first. A device point for which `in_other_lumen` holds gives no
/// handle: lumens connect (the aorta's runs on into the iliacs), and a device passing from
/// one into the other is outside the first's wall there without pushing on it.
/// `device_entry`, with pair_in_order: where the device enters the vessel at its proximal
/// end (an iliac's junction with the aorta, where the aorta's deformation put it); the
/// device's run from there (device_run_from) is paired from the first section on.
std::vector<Handle> select_control_points(const geometry::TriangleMesh& mesh, const geometry::RayCaster& caster,
                                          const geometry::Polyline& centerline, const RadiusProfile& radius,
                                          const geometry::Polyline& device, const ControlPointOptions& options,
                                          const LumenTest& in_other_lumen = {},
                                          const std::optional<Eigen::Vector3d>& device_entry = std::nullopt);

/// Turns handles into vertex targets: each handle moves the three vertices of its triangle
/// by s; a vertex touched by several handles gets their barycentric-weighted mean shift.
std::map<int, Eigen::Vector3d> handle_vertex_targets(const geometry::TriangleMesh& mesh, const std::vector<Handle>& handles);

}  // namespace evar::deform
