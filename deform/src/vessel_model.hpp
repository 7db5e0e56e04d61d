#pragma once
// What SceneDeformer computes once per vessel before any device is known (its skeleton,
// radius profile, prefactored ARAP system and, for an iliac, where its top is bound to
// the aorta), and the solve of one vessel for a device pose.
#include <Eigen/Core>
#include <map>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "evar/deform/arap_system.hpp"
#include "evar/deform/control_points.hpp"
#include "evar/deform/scene_deformation.hpp"
#include "evar/deform/skeleton.hpp"
#include "evar/geometry/closest_point.hpp"
#include "evar/geometry/ray_caster.hpp"

namespace evar::deform {

// What is computed once per vessel, before any device is known.
struct SceneDeformer::VesselModel {
  const geometry::Vessel* vessel = nullptr;
  std::optional<geometry::RayCaster> caster;
  Skeleton skeleton;
  RadiusProfile radius;
  std::shared_ptr<const ArapSystem> system;  ///< surface (+ skeleton) terms, tether, ordering
  std::vector<int> isolated;                 ///< vertices no face uses
  bool closed = false;                       ///< the mesh has an inside (ray parity works)
  /// Iliacs: the top vertices (foot on the centerline within bind_length of its start),
  /// each with the closest point of the undeformed aortic surface (face, barycentric).
  std::vector<std::pair<int, geometry::SurfacePoint>> junction;
  Eigen::Vector3d top_centroid = Eigen::Vector3d::Zero();  ///< of the junction vertices
  double junction_gap_mm = 0.0;  ///< the farthest junction vertex from its aortic point
  /// With no junction: where along its centerline the mesh begins (its vertices' least
  /// foot arc length) and how far its nearest vertex is from the centerline's start (mm).
  double mesh_begins_at_mm = 0.0, nearest_vertex_to_start_mm = 0.0;
  double skeleton_ms = 0.0, weights_ms = 0.0;
};

namespace detail {

using VesselModel = SceneDeformer::VesselModel;

/// The vessel's skeleton, radius profile and prefactored ARAP system (vessel_model.cpp).
std::unique_ptr<VesselModel> make_model(const geometry::Vessel& v, const DeformOptions& options);

/// Binds an iliac's top vertices to the closest points of the aortic surface (vessel_model.cpp).
void bind_junction(VesselModel& m, const geometry::TriangleMesh& aorta, double bind_length_mm);

/// Skeleton-based (or plain) ARAP for one vessel: device handles plus `fixed` vertex
/// targets, re-selected on the deformed surface until they settle (vessel_solve.cpp).
geometry::Vertices deform_vessel(const VesselModel& m, const geometry::Polyline& device,
                                 const std::map<int, Eigen::Vector3d>& fixed, const DeformOptions& options,
                                 const LumenTest& in_other_lumen, const geometry::Vertices* previous,
                                 VesselReport& report);

/// Marks in `erased` the aortic vertices the carrier iliac now represents (stump_erasure.cpp).
void mark_aortic_stump(const VesselModel& carrier, const geometry::Vertices& carrier_deformed,
                       const geometry::TriangleMesh& aorta_rest, const geometry::Vertices& aorta_deformed,
                       std::vector<char>& erased);

/// Keeps the faces of `faces` that touch no erased vertex of `dv` (vertices keep their
/// order) and reports what went and how far the kept vertices moved from `rest`
/// (stump_erasure.cpp).
void apply_erasure(DeformedVessel& dv, const geometry::Faces& faces, const geometry::Vertices& rest, VesselReport& r);

}  // namespace detail
}  // namespace evar::deform
