#pragma once
// Where the pelvis lies in the fluoroscopy against where the registration puts it. The models
// are registered to the renal arteries (paper 2.3); the pelvis, and the iliacs it holds, may
// lie elsewhere on the table (deform/pelvis_shift.hpp). Its bones are in every fluoroscopy
// frame: the CT's pelvis (a closed bone surface) is projected as the bone's thickness along
// each ray, the image of that thickness is matched to the frame by gradient correlation
// (Penney et al. 1998: edges, not grey levels, so soft tissue, gas and exposure do not
// matter), each view giving the 2D shift of the bones, and the views together the 3D
// translation. Blocks of the bones' image matched on their own give local shifts at the
// bone they show; where enough of them spread over two views, they give the pelvis's turn
// too (a registration to the renal arteries that is off by a few degrees is off by
// centimetres' worth of lever at the pelvis). A view whose match is weak (no bones in its field, or something else there)
// is not used, and with fewer than two views, or views too close to fix the depth, the
// registration is refused: a guess would move the iliacs by its error.
#include <Eigen/Core>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/ray_caster.hpp"

namespace evar::geometry {

/// The bone's thickness (mm) along the ray of every `step_px`-th detector pixel of P
/// (bones' coordinates → detector pixels): the chords of the ray inside each closed surface
/// of `bones`, summed. A cols/step x rows/step CV_32F image (rounded up); its pixel (i, j)
/// is the ray through detector pixel (j·step + (step−1)/2, i·step + (step−1)/2), the centre of
/// the step x step block it stands for.
/// With `mean_depth_mm`, also the thickness-weighted mean distance from the source of the
/// bone along each ray (0 where there is none).
cv::Mat bone_thickness_image(const RayCaster& bones, const ProjectionMatrix& P, int cols, int rows, int step_px,
                             cv::Mat* mean_depth_mm = nullptr);

struct PelvisView {
  ProjectionMatrix P_ct;  ///< CT LPS mm → detector pixels: the view with the registration (and table) in it
  cv::Mat frame;       ///< the detector image (one channel, any depth), as the detector gave it: brighter where less is absorbed
  std::string name;    ///< how the view is named in reasons ("frame 12, LAO 35")
};

struct PelvisRegistrationOptions {
  int step_px = 4;                  ///< detector pixels per pixel of the matched images
  double max_shift_mm = 30.0;       ///< searched in each direction (at the bones, in the detector's plane)
  double min_correlation = 0.5;     ///< gradient correlation a view's match needs to count
  double min_bone_fraction = 0.03;  ///< of a view's matched pixels, the share over the bones
  double min_separation_deg = 15.0; ///< between two views' rays to the bones, to fix the depth
  int max_rounds = 15;              ///< render, match, solve, until settled (else refused)
  /// Settled: a round's step moves no bone further than this (the turn's steps are halved
  /// each time one reverses the last, so rounds that swing about the pose settle).
  double settled_mm = 1.0;
  bool turn = true;                 ///< solve for the turn too where the blocks allow (false: translation only)
  int blocks_across = 8;            ///< a block's side is the frame's width over this (64 px at 512)
  int min_blocks = 8;               ///< matched blocks (over two views or more) a turn needs
  double max_turn_deg = 10.0;       ///< a larger turn is refused as a disagreement of the views
  /// Combinations of turn and translation that the blocks measure at under this share of
  /// the best-measured one (singular values of the solve) are left out of each step (a
  /// truncated SVD): from two views a turn about an axis both see alike is nearly a
  /// translation, and noise would turn the pelvis along it round after round.
  double truncate_below = 0.05;
};

struct PelvisViewMatch {
  std::string name;
  bool used = false;
  double correlation = 0.0;      ///< gradient correlation at the match (last round)
  Eigen::Vector2d shift_px{0, 0};  ///< last round's measured shift (detector pixels)
  std::string reason;            ///< why a view was not used ("" when used)
};

struct PelvisRegistration {
  bool found = false;
  /// The pelvis's pose against where the registration put it, in CT LPS: a bone point x lies
  /// at rotation·(x − pivot_mm) + pivot_mm + shift_mm.
  Eigen::Vector3d shift_mm = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d pivot_mm = Eigen::Vector3d::Zero();  ///< the bones' centroid
  bool turned = false;       ///< the turn was solved for (enough blocks matched); otherwise a translation
  int blocks = 0;            ///< blocks matched in the last round (all views)
  std::vector<PelvisViewMatch> views;
  double residual_px = 0.0;  ///< RMS of the used views' shifts in the last round (what the pose before it left)
  int rounds = 0;
  std::string refused;       ///< why nothing was found ("" when found)

  /// How far `rotation` turns the pelvis (degrees, about its own axis).
  double turn_deg() const;
};

/// How well the pelvis's bones, where the view's projection puts them, match its frame
/// alone: the gradient correlation at the best shift within max_shift_mm (register_pelvis's
/// first round on this one view; `used` when it counts). What a frame turned or mirrored
/// against its projection does not reach in an oblique view (node/picture_orientation.hpp).
/// std::invalid_argument for implausible options.
PelvisViewMatch match_pelvis_view(const RayCaster& bones, const PelvisView& view,
                                  const PelvisRegistrationOptions& options = {});

/// std::invalid_argument "register_pelvis: implausible options (...)" for options no
/// registration runs with.
void check_options(const PelvisRegistrationOptions& options);

/// Registers the pelvis `bones_ct` (CT LPS) to the views: its pose in the CT's axes, a turn
/// where the blocks allow, else a translation (what deform/pelvis_shift.hpp takes). Never
/// throws for what the images show: a refusal says why (also a pose that did not settle in
/// max_rounds). std::invalid_argument for an empty bone mesh, implausible options or no views.
PelvisRegistration register_pelvis(const TriangleMesh& bones_ct, const std::vector<PelvisView>& views,
                                   const PelvisRegistrationOptions& options = {});

}  // namespace evar::geometry
