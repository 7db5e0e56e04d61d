#pragma once
// The vessel skeleton of the paper (2.3) and its Laplacian L_s (Zhang et al. 2010): the
// mesh is sliced every `plane_spacing_mm` perpendicular to its centerline; from each
// plane's centre `rays_per_plane` equiangular rays are cast in the plane and their wall
// hits are skeleton points bound to the surface (barycentric in the hit triangle). Each
// plane centre is an extra unknown joined to its hits (spokes) and to the neighbouring
// centres (axis). Spokes and axis edges enter the ARAP energy as terms of their centre's
// cell, so a cross-section resists flattening and the tube keeps its volume; see
// docs/DEFORMATION.md for why the stacked system stays symmetric positive definite.
#include <Eigen/Core>
#include <vector>

#include "evar/deform/arap_system.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/ray_caster.hpp"
#include "evar/geometry/triangle_mesh.hpp"

namespace evar::deform {

struct SkeletonOptions {
  double plane_spacing_mm = 5.0;  ///< distance between slicing planes along the centerline
  int rays_per_plane = 6;         ///< equiangular rays per plane
  double weight = 1.0;            ///< w of spoke and axis terms (cotangent weights are ~0.5-1)
  int min_hits_per_plane = 3;     ///< planes with fewer wall hits are dropped
};

struct Skeleton {
  struct Spoke {
    int centre;                   ///< index into centres
    int face;                     ///< hit triangle
    Eigen::Vector3d barycentric;  ///< of the hit in the triangle
    Eigen::Vector3d hit;          ///< mm
  };
  std::vector<Eigen::Vector3d> centres;  ///< plane centres on the centerline (mm)
  std::vector<double> arc_mm;            ///< their arc length along the centerline
  std::vector<double> radius_mm;         ///< mean spoke length per plane
  std::vector<Spoke> spokes;             ///< wall hits
};

/// Builds the skeleton. Rays that miss the mesh (open ends, a centerline leaving the
/// lumen) are skipped; planes with too few hits are dropped.
Skeleton build_skeleton(const geometry::RayCaster& caster,
                        const geometry::Polyline& centerline, const SkeletonOptions& options = {});

/// Appends one cell per skeleton centre (spokes + axis edges) to `terms`; centre k is
/// unknown `first_unknown + k`, whose rest position is centres[k]. terms.num_unknowns must
/// already include them.
void append_skeleton_terms(ArapTerms& terms, const geometry::TriangleMesh& mesh, const Skeleton& skeleton,
                           int first_unknown, double weight);

/// Vessel radius along the centerline, interpolated from the skeleton's planes.
struct RadiusProfile {
  std::vector<double> arc_mm, radius_mm;
  double at(double arc) const;  ///< clamped at the ends; throws if empty
};
RadiusProfile radius_profile(const Skeleton& skeleton);

}  // namespace evar::deform
