#pragma once
// Open 3D polylines (centerlines, the device): arc length, resampling, projection and
// rotation-minimizing frames.
#include <Eigen/Core>
#include <vector>

namespace evar::geometry {

using Polyline = std::vector<Eigen::Vector3d>;

/// Cumulative arc length (mm) at each point; size = points.size(), first entry 0.
std::vector<double> arc_lengths(const Polyline& points);

/// Points every `step_mm` along the curve, first and last point included (the last
/// interval may be shorter). Consecutive duplicate points are skipped.
Polyline resample(const Polyline& points, double step_mm);

/// Both end points and points every `step_mm` between them, the gaps left at either end
/// equal: the same points (in reverse order) for the reversed polyline.
Polyline resample_symmetric(const Polyline& points, double step_mm);

struct PolylineProjection {
  Eigen::Vector3d point;   ///< closest point on the polyline
  double arc_length_mm;    ///< its arc length from the first point
  double distance_mm;      ///< |query - point|
  bool beyond_start;       ///< the query lies before the first point (clamped there)
  bool beyond_end;         ///< the query lies past the last point (clamped there)
  Eigen::Vector3d tangent; ///< unit tangent of the segment holding `point`
};

/// Closest point on the polyline (needs >= 2 distinct points).
PolylineProjection project_onto(const Polyline& points, const Eigen::Vector3d& query);

/// project_onto for many queries against one polyline: segment lengths and arc lengths
/// computed once, and a segment to try first (e.g. the previous query's, for queries
/// that walk along a curve), after which all other segments are ruled out by one
/// squared distance each. Results equal project_onto's, ties included.
class PolylineProjector {
 public:
  explicit PolylineProjector(const Polyline& points);
  /// `hint`: a segment index to try first (-1: none). `segment_out`: the segment found.
  PolylineProjection project(const Eigen::Vector3d& query, int hint = -1, int* segment_out = nullptr) const;

 private:
  const Polyline* points_;
  std::vector<double> length_, arc_;
};

/// Image curves (px): points evenly spaced along arc length, at most `step_px` apart, ends
/// kept; a curve of zero length gives its first point.
std::vector<Eigen::Vector2d> resample_2d(const std::vector<Eigen::Vector2d>& points, double step_px);

/// Distance from a 2D point to a 2D polyline (image curves, px); infinity for fewer than 2 points.
double distance_to_polyline_2d(const Eigen::Vector2d& p, const std::vector<Eigen::Vector2d>& line);

/// Point and unit tangent at arc length s (clamped to [0, length]).
Eigen::Vector3d point_at(const Polyline& points, const std::vector<double>& arc, double s);
Eigen::Vector3d tangent_at(const Polyline& points, const std::vector<double>& arc, double s);

/// Rotation-minimizing frame (double reflection, Wang et al. 2008) along the points:
/// for each point a unit tangent t and a unit normal n orthogonal to it that does not
/// twist around the curve. The binormal is t x n.
struct Frame {
  Eigen::Vector3d tangent, normal;
};
std::vector<Frame> rotation_minimizing_frames(const Polyline& points);

}  // namespace evar::geometry
