#pragma once
// The device in 3D from its curves in two fluoroscopy views with known projections.
//
//   1. both curves resampled evenly along arc length (tip first);
//   2. correspondences by dynamic programming over (i, j) pairs with the ordering
//      constraint (both indices only advance): each matched pair scores its epipolar
//      distance (symmetric, px) against a reward, so the alignment covers the stretch seen
//      in both views and no more (a local alignment: the curves leave the fields at
//      different places);
//   3. for each matched point of view 1, the exact crossing of its epipolar line with the
//      curve of view 2 near the match; where that line runs within `grazing_deg` of the
//      curve, the crossing is ill-determined and the point is marked unreliable;
//   4. triangulation (linear, homogeneous); unreliable points keep their ray in view 1 and
//      take their depth along it interpolated along arc length between reliable ones.
//      Nothing is extrapolated beyond the outermost reliable points, and an interpolated
//      stretch longer than `max_gap_mm` cuts the curve (the longest piece is kept): a
//      point moved along its view-1 ray only slides along its epipolar line in view 2,
//      so a wrong depth there reprojects onto both curves and no residual can catch it;
//   5. Gaussian smoothing along 3D arc length (the window shrinks at the ends), even
//      resampling, and per point the reprojection residual: the distance (px) of its
//      projection to the curve in each view, the larger of the two.
//
// Both readings of curve 2 (as given and reversed) are aligned: a segmentation cannot
// always tell the device's ends apart. A shape symmetric about the epipolar geometry (a
// crossover catheter's two limbs at the same heights in a LAO/RAO pair) matches both ways
// with equal residuals; then both readings are returned, and only the anatomy can choose.
#include <Eigen/Core>
#include <stdexcept>
#include <string>
#include <vector>

#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/polyline.hpp"

namespace evar::geometry {

struct ReconstructionOptions {
  double min_separation_deg = 20.0;  ///< refuse views whose rays cross at less than this (or more than 180 minus this)
  double sample_step_px = 2.0;       ///< resampling of the 2D curves for matching
  double match_reward_px = 2.0;      ///< epipolar distances below this count in favour of a match
  double grazing_deg = 15.0;         ///< epipolar line within this of the curve: unreliable
  double smoothing_mm = 1.5;         ///< Gaussian σ along the 3D curve
  double output_step_mm = 1.0;       ///< spacing of the output points
  /// Longest stretch whose depth is interpolated between reliable points. Over L the depth
  /// of a curve bent with radius R departs from the straight interpolation by about
  /// L²/(8R): 0.5 mm for 10 mm at R = 25 mm, a tight iliac bend.
  double max_gap_mm = 10.0;
  /// The reading of curve 2 that aligns less well is returned too when its alignment
  /// scores at least this share of the better one's.
  double ambiguity_ratio = 0.8;
};

struct Reconstruction {
  Polyline points;                   ///< world mm, evenly spaced, in curve 1's order (tip first when it is)
  std::vector<double> residual_px;   ///< per point: reprojection distance to the curves (max of both views)
  std::vector<char> reliable;        ///< per point: 0 where it was filled along arc length
  double separation_deg = 0.0;       ///< angle between the two viewing directions
  double mean_residual_px = 0.0;
  double max_residual_px = 0.0;
  double reliable_fraction = 0.0;
  double matched_fraction_1 = 0.0;   ///< share of curve 1 (and 2) that found a partner in the other view
  double matched_fraction_2 = 0.0;
  /// Share of the matched stretch of curve 1 (by its arc length) kept: the rest ran along
  /// the epipolar lines beyond the outermost reliable points or across a gap too long.
  double kept_fraction = 1.0;
  bool second_curve_reversed = false;  ///< curve 2 ran the other way from curve 1 and was matched reversed
  float alignment_score = 0.0f;        ///< the epipolar alignment's score (about match_reward_px per matched point)
};

/// Thrown for view pairs or curves that cannot give a 3D curve; what() says why.
class ReconstructionError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Angle (degrees) between the viewing directions of two projections.
double view_separation_deg(const ProjectionMatrix& P1, const ProjectionMatrix& P2);

/// Fundamental matrix F with x2ᵀ F x1 = 0 for corresponding pixels (homogeneous).
Eigen::Matrix3d fundamental_matrix(const ProjectionMatrix& P1, const ProjectionMatrix& P2);

/// The 3D point whose projections are x1 and x2 (linear triangulation).
Eigen::Vector3d triangulate(const ProjectionMatrix& P1, const Eigen::Vector2d& x1, const ProjectionMatrix& P2,
                            const Eigen::Vector2d& x2);

/// Every reading of the two curves as one device: one, or two when the device's shape
/// is symmetric about the views' epipolar geometry (curve 2 matched as given and reversed
/// align nearly as well, ReconstructionOptions::ambiguity_ratio); the better first.
/// Throws ReconstructionError when the views are closer than min_separation_deg (or that
/// close to facing each other), a projection is singular, a curve has fewer than 2 points
/// or is far longer than any detector, or too little of the curves can be matched or
/// reliably triangulated; std::invalid_argument for bad options.
std::vector<Reconstruction> reconstruct_two_view_readings(const std::vector<Eigen::Vector2d>& curve1, const ProjectionMatrix& P1,
                                                          const std::vector<Eigen::Vector2d>& curve2, const ProjectionMatrix& P2,
                                                          const ReconstructionOptions& options = {});

/// The one reading of reconstruct_two_view_readings; ReconstructionError also when there
/// are two (the caller has no anatomy to choose by).
Reconstruction reconstruct_two_view(const std::vector<Eigen::Vector2d>& curve1, const ProjectionMatrix& P1,
                                    const std::vector<Eigen::Vector2d>& curve2, const ProjectionMatrix& P2,
                                    const ReconstructionOptions& options = {});

}  // namespace evar::geometry
