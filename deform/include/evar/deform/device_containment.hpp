#pragma once
// How much of the device the deformed vessels fail to contain: the check after every
// deformation that a wire left outside the roadmap is reported, never passed on silently.
//
// The device is sampled every 0.5 mm; a sample is inside when it lies inside the wall of
// any vessel (surface_side.hpp). Otherwise the nearest surface decides: outside when it is
// a wall, not judged when it is an opening the sample lies beyond (past the end of the
// meshes, or in the seam between the aorta's erased stump and the iliac that replaced it)
// or a cap closing a vessel where its segmentation stopped, where the lumen may go on. A
// sample outside a wall but past that vessel's centerline's ends is not judged either.
#include <string>
#include <vector>

#include "evar/geometry/polyline.hpp"
#include "evar/geometry/triangle_mesh.hpp"

namespace evar::deform {

/// A centre line more than this beyond the wall counts as outside (mm): a tenth of a
/// 0.035" wire's radius, far above rounding and far below what would show on an overlay.
inline constexpr double kOutsideToleranceMm = 0.05;

/// Warn when the device's centre line lies this far beyond a wall (mm): more than a
/// 0.035" (0.89 mm) wire's own width outside the roadmap, which shows on the overlay.
/// Less is the solver's residue (up to 0.47 mm seen on the simulator's paper-level
/// sessions, docs/DEFORMATION.md), reported but not warned of.
inline constexpr double kWarnDepthMm = 1.0;

struct OutsideStretch {
  double from_mm = 0.0, to_mm = 0.0;  ///< arc length along the device from its first point
  double max_depth_mm = 0.0;          ///< farthest of its samples from the nearest wall
  std::string nearest_vessel;         ///< the vessel whose wall its deepest sample is nearest
};

struct DeviceContainment {
  double device_length_mm = 0.0;
  double outside_length_mm = 0.0;     ///< total length of the stretches
  double outside_max_depth_mm = 0.0;  ///< deepest of them; 0 when none
  double unjudged_length_mm = 0.0;    ///< beyond an opening and inside no vessel
  std::vector<OutsideStretch> stretches;
};

struct NamedSurface {
  std::string name;
  const geometry::TriangleMesh* mesh = nullptr;  ///< faces wound outward
  /// Where the vessel is claimed to contain the device (optional): outside its wall counts
  /// only for a sample that projects within this centerline's ends, as the control points
  /// take only such device points (a device leaving past a vessel's end is in vessels the
  /// scene does not hold).
  const geometry::Polyline* centerline = nullptr;
  /// The mesh's caps (optional): one flag per face, non-zero where the face closes the
  /// vessel where its segmentation stopped. They bound the lumen, but a sample outside
  /// whose nearest surface is a cap is past the vessel's end, not judged.
  std::vector<char> cap_faces;
};

/// Measures `device` against the union of `vessels`.
DeviceContainment measure_device_containment(const std::vector<NamedSurface>& vessels, const geometry::Polyline& device,
                                             double sample_step_mm = 0.5);

/// Past the warning threshold: some stretch lies more than kWarnDepthMm beyond the wall.
bool leaves_device_outside(const DeviceContainment& c);

/// "6.0 mm of the device lies outside the vessels, up to 1.1 mm beyond the wall of
/// 'iliac_right' (from 132.5 to 138.5 mm along it)", naming the deepest stretch; "" when
/// none does.
std::string describe_outside(const DeviceContainment& c);

}  // namespace evar::deform
