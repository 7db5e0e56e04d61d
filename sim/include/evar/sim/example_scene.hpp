#pragma once
// A deterministic synthetic aorto-iliac scene for demos, tests and benchmarks: an
// abdominal aorta with an infrarenal aneurysm, two tortuous common+external iliac
// arteries, four ostium landmarks and a stiff guidewire that is straighter than the
// iliac it runs in (so the undeformed meshes do not contain it, as in real EVAR).
//
// Everything is in patient LPS millimetres: x = patient Left, y = Posterior,
// z = Superior. The aortic bifurcation is at the origin.
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "evar/geometry/markups.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/geometry/triangle_mesh.hpp"

namespace evar::sim {

/// Adult anatomy defaults. The seed perturbs aneurysm position and size, aortic bow,
/// iliac course and tortuosity by a few millimetres (times `variation`); the same
/// parameters always give bit-identical output on any platform.
struct ExampleSceneParams {
  std::uint64_t seed = 1;
  double variation = 1.0;  ///< scale of the seeded perturbations; 0 = the nominal anatomy

  // Aorta, centerline from z = aorta_top_z_mm down to the bifurcation at the origin.
  double aorta_top_z_mm = 140.0;
  double aorta_radius_top_mm = 11.5;          ///< suprarenal
  double aorta_radius_bifurcation_mm = 9.5;   ///< just above the bifurcation
  double aorta_bow_anterior_mm = 6.0;         ///< mid-aorta displacement towards -y
  double aorta_bow_left_mm = 3.0;             ///< mid-aorta displacement towards +x
  double aneurysm_centre_z_mm = 60.0;
  double aneurysm_length_mm = 70.0;           ///< fusiform sac extent along z
  double aneurysm_max_radius_mm = 25.0;
  double renal_z_mm = 110.0;                  ///< renal ostia height

  // Iliacs (common + external, one tube each), first point above the bifurcation.
  double iliac_start_above_bifurcation_mm = 8.0;
  double iliac_start_lateral_mm = 4.0;        ///< |x| of the first centerline point
  double iliac_end_z_mm = -140.0;
  double iliac_end_lateral_mm = 70.0;         ///< |x| of the distal end
  double iliac_end_anterior_mm = 15.0;        ///< distal end towards -y
  double iliac_radius_proximal_mm = 6.0;
  double iliac_radius_distal_mm = 4.5;
  double iliac_tortuosity_x_mm = 13.0;        ///< amplitude of the lateral S-bend
  double iliac_tortuosity_y_mm = 10.0;        ///< amplitude of the antero-posterior bends
  double internal_iliac_arc_mm = 55.0;        ///< ostium distance along the iliac centerline

  // Device: guidewire through one iliac (right unless device_in_left_iliac), tip in the aorta.
  bool device_in_left_iliac = false;
  double device_tip_z_mm = 100.0;
  double device_stiffness_length_mm = 40.0;   ///< bending stiffness as a length: the wire
                                              ///< follows bends much longer than 2 pi times
                                              ///< this and cuts across shorter ones
  double device_thickness_mm = 0.9;

  // Resolution (vertex targets for tube_options_for_vertex_count).
  int aorta_vertices = 7500;
  int iliac_vertices = 3500;
};

struct ExampleVessel {
  std::string name;                          ///< "aorta", "iliac_left", "iliac_right"
  geometry::VesselKind kind = geometry::VesselKind::Aorta;
  geometry::TriangleMesh mesh;               ///< closed, outward, LPS mm
  std::vector<Eigen::Vector3d> centerline;   ///< #P points, proximal to distal, 1 mm apart
  std::vector<double> radii_mm;              ///< #P lumen radii at the centerline points
};

/// How far a device leaves one vessel's undeformed lumen, measured as (distance to the
/// vessel centerline) - (local radius) at each device point whose projection falls
/// within the centerline (not beyond either end).
struct DeviceClearance {
  std::string vessel;
  double max_outside_mm = 0.0;     ///< largest value; <= 0 when the device stays inside
  double length_outside_mm = 0.0;  ///< device length (mm) with a positive value
};

struct ExampleScene {
  std::vector<ExampleVessel> vessels;           ///< aorta, iliac_left, iliac_right
  std::vector<geometry::ControlPoint> landmarks;  ///< renal_left, renal_right,
                                                ///< internal_iliac_left, internal_iliac_right;
                                                ///< each exactly on its vessel's surface
  std::vector<Eigen::Vector3d> device;          ///< tip (in the aorta) first, access point
                                                ///< (that iliac's distal end) last; 1 mm apart
  double device_thickness_mm = 0.9;
  /// The pelvis's bones (body_phantom.hpp's pelvis_mesh), written as the scene's "pelvis"
  /// when it has vertices; none in the example scene.
  geometry::TriangleMesh pelvis;
  std::vector<DeviceClearance> device_clearance;  ///< one per vessel, same order; for a
                                                  ///< vessel the device does not run in
                                                  ///< (iliac_left) the figures are large

  /// The vessel called `name`; std::out_of_range if there is none.
  const ExampleVessel& vessel(std::string_view name) const;
};

/// Builds the scene. Throws std::invalid_argument for parameters that cannot give a valid
/// anatomy (non-positive radii or lengths, the sac narrower than the aorta, vertex
/// targets too small, a device tip outside the aortic span).
ExampleScene make_example_scene(const ExampleSceneParams& params = {});

/// Clearance of `device` (LPS mm) against a tube with `centerline` (#P >= 2, mm) and
/// per-point `radii_mm` (#P), linearly interpolated in arc length.
DeviceClearance measure_device_clearance(const std::vector<Eigen::Vector3d>& device,
                                         const std::vector<Eigen::Vector3d>& centerline,
                                         const std::vector<double>& radii_mm);

/// The scene as load_scene() would give it for the files write_example_scene() writes
/// (mesh format binary STL, paths relative to "example/"), without touching the disk.
geometry::Scene to_scene(const ExampleScene& scene);

/// Writes the scene as a directory that load_scene() reads: dir/scene.json,
/// dir/<vessel>.<stl|ply|obj> (extension from `format`), dir/<vessel>.centerline.mrk.json
/// (Curve), dir/landmarks.mrk.json (Fiducial, labels kept) and dir/device.mrk.json
/// (Curve, tip first). Creates `dir` if needed; overwrites these files. Throws
/// std::runtime_error (from the geometry writers) if a file cannot be written.
void write_example_scene(const ExampleScene& scene, const std::filesystem::path& dir,
                         geometry::MeshFormat format = geometry::MeshFormat::StlBinary);

}  // namespace evar::sim
