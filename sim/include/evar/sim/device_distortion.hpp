#pragma once
// The ground truth of a synthetic patient: how an inserted stiff device distorts the
// vessels. Deliberately NOT the product's ARAP, so evaluations are not circular.
//
// Model. Each vessel centerline is an elastic beam on an elastic foundation: bending
// stiffness λ = l⁴ (l a bending length in mm, varying along the vessel), the surrounding
// tissue as unit springs toward the preoperative course. Real tethers hold it: the aortic
// top (visceral branches) and the iliac's distal end (inguinal ligament, access sheath)
// are fixed; the part of each iliac inside the aortic lumen moves with the aortic centerline. The
// device pushes by contact: wherever it crosses a cross-section outside the lumen (radius
// minus Δd/2 minus a clearance), that section is moved until it is inside (an active-set
// obstacle problem, solved to 0.01 mm). Finally every cross-section is translated with its
// centerline point (docs/SYNTHETIC_PATIENTS.md says why not turned), so meshes keep their
// vertex order and section shapes; landmarks move with their vessel.
#include <string>
#include <vector>

#include "evar/geometry/markups.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/triangle_mesh.hpp"
#include "evar/sim/example_scene.hpp"

namespace evar::sim {

struct DistortionOptions {
  double aorta_bending_length_mm = 45.0;
  double common_iliac_bending_length_mm = 30.0;    ///< stiffer (calcified) proximal part
  double external_iliac_bending_length_mm = 20.0;  ///< more compliant distal part
  double common_iliac_length_mm = 55.0;            ///< where the stiffness profile changes
  double clearance_mm = 0.3;  ///< gap kept between the device surface and the wall
  int max_contact_rounds = 200;
};

struct VesselDistortion {
  std::string name;
  geometry::TriangleMesh mesh;    ///< distorted; same faces and vertex order as the input
  geometry::Polyline centerline;  ///< distorted; same points
  double max_displacement_mm = 0.0;  ///< largest centerline displacement
  int contact_sections = 0;          ///< sections the device pushes in the solution
};

struct DeviceDistortion {
  std::vector<VesselDistortion> vessels;          ///< same order as the scene's vessels
  std::vector<geometry::ControlPoint> landmarks;  ///< same labels and order, moved
  std::string carrier;                            ///< the iliac the device runs in
  int rounds = 0;                                 ///< contact rounds used (all passes)
  /// Extra passes that pushed sections whose swept walls missed device points (a tight
  /// bend, where sections and meshes disagree); 0 for most patients.
  int mesh_passes = 0;
  /// Largest remaining intrusion (mm) of the device surface plus clearance into a wall,
  /// measured on the section model; <= 0.01 when the contact problem converged.
  double max_intrusion_mm = 0.0;
  /// The check on the meshes themselves: device points neither inside the union of the
  /// distorted meshes (ray parity) nor within Δd of a wall. Non-zero where the section
  /// model and the meshes disagree (very tortuous iliacs pushed into tight bends).
  int device_points_outside = 0;
  double worst_outside_mm = 0.0;     ///< the farthest of those from a wall
  std::size_t worst_outside_point = 0;  ///< its device index (tip = 0)
  std::string worst_outside_vessel;     ///< the vessel whose wall is nearest it
};

/// Distorts `scene`'s vessels (closed tubes swept along their centerlines with
/// radii_mm) so they contain `scene.device` of `scene.device_thickness_mm`. The carrier
/// iliac is the one whose distal end is nearest the device's access end. Throws
/// std::invalid_argument for a scene without an aorta or iliac, or a device of < 2 points;
/// std::runtime_error when the contact problem does not converge. Check
/// device_points_outside before using the result as ground truth (make_patient does).
DeviceDistortion distort_by_device(const ExampleScene& scene, const DistortionOptions& options = {});

/// Re-sweeps `mesh` (around `centerline`) along `moved` (same point count): each vertex moves
/// with the displacement of the place on the centerline it projects to (linear between
/// points). With moved == centerline the mesh comes back unchanged.
geometry::TriangleMesh resweep(const geometry::TriangleMesh& mesh, const geometry::Polyline& centerline,
                               const geometry::Polyline& moved);

}  // namespace evar::sim
