#pragma once
// A closed triangle tube swept along a 3D centerline: the synthetic stand-in for a
// segmented vessel. Rings of `segments_around` vertices are placed at equal arc-length
// steps, oriented by rotation-minimizing frames so the tube does not twist, and every
// other ring is turned by half a segment so the triangles are close to equilateral.
#include <Eigen/Core>
#include <functional>
#include <vector>

#include "evar/geometry/triangle_mesh.hpp"

namespace evar::sim {

/// Tube radius (mm) as a function of arc length s (mm) from the first centerline point.
using RadiusProfile = std::function<double(double s_mm)>;

struct TubeOptions {
  int segments_around = 32;      ///< vertices per ring, >= 3
  double ring_spacing_mm = 1.0;  ///< requested arc-length step between rings (> 0); the
                                 ///< step used is length / round(length / step), so both
                                 ///< ends get a ring and all steps are equal
  bool capped = true;            ///< close each end with a centre vertex and a fan
};

/// Sweeps a tube along `centerline` (#P >= 2 points, LPS mm; consecutive duplicates are
/// ignored) with radius `radius(s)` (mm, finite and > 0 along the whole length).
///
/// Vertex layout: ring k (k = 0 .. #rings-1, from the first centerline point) holds
/// vertices k*N .. k*N+N-1 with N = segments_around; when capped, the start cap centre is
/// vertex #rings*N and the end cap centre #rings*N+1 (both on the centerline ends).
/// Faces are oriented with outward normals (counter-clockwise seen from outside). The
/// capped tube is closed and manifold when the radius stays below the centerline's radius
/// of curvature (otherwise rings intersect; not checked).
/// Throws std::invalid_argument for fewer than 2 distinct points, segments_around < 3,
/// a non-positive or non-finite ring spacing, or a non-positive/non-finite radius.
geometry::TriangleMesh tube_mesh(const std::vector<Eigen::Vector3d>& centerline,
                                 const RadiusProfile& radius, const TubeOptions& options = {});

/// Same, with one radius per centerline point (mm; radii.size() == centerline.size()),
/// interpolated linearly in arc length between points.
geometry::TriangleMesh tube_mesh(const std::vector<Eigen::Vector3d>& centerline,
                                 const std::vector<double>& radii, const TubeOptions& options = {});

/// values[i] given at arc lengths arc[i] (non-decreasing), linearly interpolated at s and
/// held constant beyond either end: radii along a centerline.
double interpolate_along(const std::vector<double>& arc, const std::vector<double>& values, double s);

/// Number of vertices tube_mesh produces for a centerline of `length_mm` with `options`.
int tube_vertex_count(double length_mm, const TubeOptions& options);

/// Options that give about `target_vertices` vertices for a tube of `length_mm` and mean
/// radius `mean_radius_mm`, with near-equilateral triangles: the ring spacing is
/// sqrt(3)/2 times the ring's edge length 2 r sin(pi/N). The count is met to within about
/// N/2 vertices (the ring count is rounded). Throws std::invalid_argument for non-positive
/// inputs or a target below what 2 rings of 3 vertices need.
TubeOptions tube_options_for_vertex_count(double length_mm, double mean_radius_mm,
                                          int target_vertices, bool capped = true);

/// Same, measuring the length of `centerline` and the arc-length mean of `radius` along it.
TubeOptions tube_options_for_vertex_count(const std::vector<Eigen::Vector3d>& centerline,
                                          const RadiusProfile& radius, int target_vertices,
                                          bool capped = true);


}  // namespace evar::sim
