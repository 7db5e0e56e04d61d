#pragma once
// Is the picture the right way round? A video mapping (or a detector read out) that misses
// a mirror or a turn of the picture gives the node curves that are the device's picture
// mirrored or turned. Two views do not always betray it: a mirror of both pictures about
// their vertical axis keeps the epipolar geometry of views turned about the patient's long
// axis, so the device still reconstructs, as its mirror image swung through the patient,
// and the roadmap is drawn left for right. The preoperative vessels do betray it: the
// device runs inside them, give or take how far it bends them. So the pair's curves are
// taken through each of the other ways the picture could be turned and mirrored
// (picture_turn.hpp), and a way whose device lies in the vessels clearly better than the
// mapping's says the mapping is wrong. The pelvis's bones betray it too, without a device
// and whatever the device bends: in an oblique view the frame matches the CT's bones only
// the right way round (issue 31, docs/FORMATS.md, "Is the picture the right way round?").
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "evar/deform/scene_deformation.hpp"
#include "evar/geometry/pelvis_registration.hpp"
#include "evar/geometry/video_mapping.hpp"
#include "evar/node/model_adaptation.hpp"
#include "evar/node/picture_turn.hpp"
#include "evar/node/view_pair_selector.hpp"

namespace evar::node {

/// How the screen shows the picture when the node reads it `missed` by that turn (a turn
/// that brings the node's reading to the detector's picture): the display's turn against
/// the mapping, seen through `through`'s own turn and mirror (null: the frames are the
/// detector's).
PictureTurn shown_turn(const PictureTurn& missed, const geometry::VideoMapping* through);

/// How well a pair's device lies in the preoperative vessels taken one way.
struct TurnFit {
  PictureTurn turn;
  /// mean_outside_lumen_mm of the reading nearest the vessels; infinite when the curves so
  /// turned give no acceptable reconstruction (AdaptationOptions' residual and length).
  double outside_mm = std::numeric_limits<double>::infinity();
};

struct OrientationCheck {
  TurnFit as_set;                 ///< the pair as the node takes it
  std::vector<TurnFit> tried;     ///< the other turns, when they were tried (see below)
  std::optional<TurnFit> better;  ///< the turn under which the device clearly lies in the vessels instead
  /// The turns whose device lies within options.reading_margin_mm of better's, best first:
  /// the pair cannot tell them apart (two readings that close are one, as in
  /// reading_in_the_vessels).
  std::vector<PictureTurn> candidates;
  bool confirmed = false;  ///< the device lies in the vessels as taken (and, strictly, only so)
  /// "" or, with `better`, what to tell the user: the turn as shown (shown_turn), both distances.
  std::string problem;
};

/// Checks a view pair's picture orientation.
/// - A device within `options.reading_margin_mm` of the vessels as set confirms the
///   picture; `strict`, only when every other turn lies farther by the margin (a mirror of
///   symmetric vessels may read into the other iliac: a suspicion is cleared only by a
///   pair that rules it out).
/// - A device farther out, but within `options.orientation_outside_mm`, may be one that
///   bends its vessels that far: nothing else is tried, nothing is decided.
/// - Beyond (and when it gives no reconstruction at all), every other turn is
///   reconstructed, and the one whose device lies outside the lumen least, by at most the
///   margin, is `better`.
/// Both views are turned alike (one display shows them) about their own picture's
/// centre; quarter turns only when both pictures are square. `shown_through`: the mapping
/// the frames are shown through, so that `problem` says the turn as the screen shows it.
OrientationCheck check_picture_orientation(const deform::SceneDeformer& deformer, const ViewPair& pair,
                                           const AdaptationOptions& options, bool strict = false,
                                           const geometry::VideoMapping* shown_through = nullptr);

/// How well one view's frame matches the pelvis's bones as taken and turned.
struct BoneOrientationCheck {
  geometry::PelvisViewMatch as_set;  ///< as the node takes the frame
  std::vector<std::pair<PictureTurn, geometry::PelvisViewMatch>> tried;  ///< every other turn
  std::optional<std::pair<PictureTurn, double>> better;  ///< a turn that matches where as set does not (its correlation)
  /// The turns that match as well as `better` within the margin, best first: the view
  /// cannot tell them apart (a pelvis nearly symmetric under both).
  std::vector<PictureTurn> candidates;
  /// The bones match as taken, and no other turn comes within the margin of it (an AP view
  /// of a symmetric pelvis matches mirrored as well, and confirms nothing).
  bool confirmed = false;
  std::string problem;  ///< "" or, with `better`, what to tell the user
};

/// Checks one view's picture orientation by its bones (geometry::match_pelvis_view): the
/// frame as taken and every other turn that keeps its shape. A turn whose match counts
/// (`used`: correlation ≥ options.min_correlation, the peak inside the searched range) and
/// beats as taken by `margin` is suspected; the best is `better`. `shown_through` as above.
BoneOrientationCheck check_bone_orientation(const geometry::RayCaster& bones, const geometry::PelvisView& view,
                                            const geometry::PelvisRegistrationOptions& options, double margin = 0.15,
                                            const geometry::VideoMapping* shown_through = nullptr);

/// The checks' verdicts over views or pairs in a row: a turn is said once `needed` checks in
/// a row found it among their candidates; a check that confirms the picture as taken
/// starts over, one that decides nothing changes nothing.
class TurnStreak {
 public:
  explicit TurnStreak(int needed = 2) : needed_(needed) {}
  /// A check found these turns better (best first; not empty). Once the streak is long
  /// enough, the turns to say: those every check of the streak found, in `candidates`'
  /// order (one when the checks single it out); empty before.
  std::vector<PictureTurn> suspect(const std::vector<PictureTurn>& candidates);
  void confirm() {
    shared_.clear();
    length_ = 0;
  }
  int length() const { return length_; }

 private:
  int needed_;
  int length_ = 0;
  std::vector<PictureTurn> shared_;  ///< the turns every check of the streak found
};

}  // namespace evar::node
