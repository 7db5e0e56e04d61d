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
//      take their depth along it interpolated along arc length between reliable ones;
//   5. Gaussian smoothing along 3D arc length (the window shrinks at the ends), even
//      resampling, and per point the reprojection residual: the distance (px) of its
//      projection to the curve in each view, the larger of the two.
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
};

struct Reconstruction {
  Polyline points;                   ///< world mm, tip first, evenly spaced
  std::vector<double> residual_px;   ///< per point: reprojection distance to the curves (max of both views)
  std::vector<char> reliable;        ///< per point: 0 where it was filled along arc length
  double separation_deg = 0.0;       ///< angle between the two viewing directions
  double mean_residual_px = 0.0;
  double max_residual_px = 0.0;
  double reliable_fraction = 0.0;
  double matched_fraction_1 = 0.0;   ///< share of curve 1 (and 2) that found a partner in the other view
  double matched_fraction_2 = 0.0;
  bool second_curve_reversed = false;  ///< curve 2 ran proximal-first and was matched reversed
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

/// Throws ReconstructionError when the views are closer than min_separation_deg (or that
/// close to facing each other), a curve has fewer than 2 points or is far longer than any
/// detector, or too little of the curves can be matched; std::invalid_argument for bad options.
Reconstruction reconstruct_two_view(const std::vector<Eigen::Vector2d>& curve1, const ProjectionMatrix& P1,
                                    const std::vector<Eigen::Vector2d>& curve2, const ProjectionMatrix& P2,
                                    const ReconstructionOptions& options = {});

}  // namespace evar::geometry
