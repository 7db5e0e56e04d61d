#include "evar/node/picture_orientation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace evar::node {

namespace {

// The mean distance outside the lumen of the reading of these curves nearest the vessels,
// or infinity when they give no reconstruction the node would take.
double outside_as_read(const deform::SceneDeformer& deformer, const std::vector<Eigen::Vector2d>& curve1,
                       const geometry::ProjectionMatrix& P1, const std::vector<Eigen::Vector2d>& curve2,
                       const geometry::ProjectionMatrix& P2, const AdaptationOptions& o) {
  double best = std::numeric_limits<double>::infinity();
  std::vector<geometry::Reconstruction> readings;
  try {
    readings = geometry::reconstruct_two_view_readings(curve1, P1, curve2, P2, o.reconstruction);
  } catch (const geometry::ReconstructionError&) {
    return best;
  }
  for (const auto& r : readings) {
    const double length_mm = r.points.size() < 2 ? 0.0 : geometry::arc_lengths(r.points).back();
    if (r.mean_residual_px > o.max_mean_residual_px || length_mm < o.min_length_mm) continue;
    best = std::min(best, mean_outside_lumen_mm(r.points, deformer));
  }
  return best;
}

}  // namespace

PictureTurn shown_turn(const PictureTurn& missed, const geometry::VideoMapping* through) {
  const PictureTurn t = inverse(missed);
  return through ? turn_as_shown(t, *through) : t;
}

namespace {

// How the roadmap is drawn over a picture shown turned so.
std::string drawn(const PictureTurn& t) {
  if (t.rotation_deg == 0) return "left for right";
  if (t.rotation_deg == 180) return t.mirror ? "upside down" : "upside down and left for right";
  return "turned";
}

// What a turn the mapping missed means, for the user.
std::string consequence(const PictureTurn& seen) {
  return "the video mapping's mirror or rotation_deg (or the zoom mode's) is likely wrong and the roadmap drawn " +
         drawn(seen);
}

}  // namespace

OrientationCheck check_picture_orientation(const deform::SceneDeformer& deformer, const ViewPair& pair,
                                           const AdaptationOptions& o, bool strict,
                                           const geometry::VideoMapping* shown_through) {
  const auto& a = pair.earlier;
  const auto& b = pair.later;
  const int cols_a = a.geometry.view.detector_cols, rows_a = a.geometry.view.detector_rows;
  const int cols_b = b.geometry.view.detector_cols, rows_b = b.geometry.view.detector_rows;
  const auto fit_of = [&](const PictureTurn& t) {
    return TurnFit{t, outside_as_read(deformer, turned_points(a.curve_px, t, cols_a, rows_a), a.geometry.P_ct,
                                      turned_points(b.curve_px, t, cols_b, rows_b), b.geometry.P_ct, o)};
  };
  OrientationCheck check;
  check.as_set = fit_of({});
  const double margin_mm = o.reading_margin_mm;
  const bool in_vessels = check.as_set.outside_mm <= margin_mm;
  if (!in_vessels && check.as_set.outside_mm <= o.orientation_outside_mm) return check;  // undecided
  if (in_vessels && !strict) {
    check.confirmed = true;
    return check;
  }
  for (const PictureTurn& t : other_turns(cols_a == rows_a && cols_b == rows_b)) check.tried.push_back(fit_of(t));
  if (in_vessels) {
    check.confirmed = std::all_of(check.tried.begin(), check.tried.end(), [&](const TurnFit& f) {
      return f.outside_mm > check.as_set.outside_mm + margin_mm;
    });
    return check;
  }
  for (const auto& fit : check.tried)
    if (fit.outside_mm <= margin_mm && (!check.better || fit.outside_mm < check.better->outside_mm)) check.better = fit;
  if (!check.better) return check;
  std::vector<TurnFit> close;
  for (const auto& fit : check.tried)
    if (fit.outside_mm <= check.better->outside_mm + margin_mm) close.push_back(fit);
  std::stable_sort(close.begin(), close.end(), [](const TurnFit& x, const TurnFit& y) { return x.outside_mm < y.outside_mm; });
  for (const auto& fit : close) check.candidates.push_back(fit.turn);
  char as_set[64];
  if (std::isfinite(check.as_set.outside_mm))
    std::snprintf(as_set, sizeof as_set, "%.1f mm as the mapping has it", check.as_set.outside_mm);
  else
    std::snprintf(as_set, sizeof as_set, "no device in them as the mapping has it");
  const PictureTurn seen = shown_turn(check.better->turn, shown_through);
  char why[256];
  std::snprintf(why, sizeof why, "the device lies in the vessels only if the picture is shown %s (%.1f mm outside them on average; %s): ",
                turn_text(seen).c_str(), check.better->outside_mm, as_set);
  check.problem = why + consequence(seen);
  return check;
}

BoneOrientationCheck check_bone_orientation(const geometry::RayCaster& bones, const geometry::PelvisView& view,
                                            const geometry::PelvisRegistrationOptions& options, double margin,
                                            const geometry::VideoMapping* shown_through) {
  BoneOrientationCheck check;
  check.as_set = geometry::match_pelvis_view(bones, view, options);
  check.confirmed = check.as_set.used;
  for (const PictureTurn& t : other_turns(view.frame.cols == view.frame.rows)) {
    auto m = geometry::match_pelvis_view(bones, {view.P_ct, turned_image(view.frame, t), view.name}, options);
    if (m.correlation > check.as_set.correlation - margin) check.confirmed = false;
    if (m.used && m.correlation >= check.as_set.correlation + margin &&
        (!check.better || m.correlation > check.better->second))
      check.better = std::make_pair(t, m.correlation);
    check.tried.emplace_back(t, std::move(m));
  }
  if (!check.better) return check;
  std::vector<std::pair<PictureTurn, double>> close;
  for (const auto& [t, m] : check.tried)
    if (m.used && m.correlation >= check.as_set.correlation + margin && m.correlation >= check.better->second - margin)
      close.emplace_back(t, m.correlation);
  std::stable_sort(close.begin(), close.end(), [](const auto& x, const auto& y) { return x.second > y.second; });
  for (const auto& [t, r] : close) check.candidates.push_back(t);
  const PictureTurn seen = shown_turn(check.better->first, shown_through);
  char why[256];
  std::snprintf(why, sizeof why, "only if the picture is shown %s (gradient correlation %.2f; %.2f as the mapping has it): ",
                turn_text(seen).c_str(), check.better->second, check.as_set.correlation);
  check.problem = "the pelvis's bones match " + view.name + " " + why + consequence(seen);
  return check;
}

std::vector<PictureTurn> TurnStreak::suspect(const std::vector<PictureTurn>& candidates) {
  if (candidates.empty()) throw std::invalid_argument("TurnStreak::suspect: no candidate turn");
  std::vector<PictureTurn> shared;
  for (const auto& t : candidates)
    if (std::find(shared_.begin(), shared_.end(), t) != shared_.end()) shared.push_back(t);
  if (shared.empty()) {
    shared_ = candidates;
    length_ = 1;
  } else {
    shared_ = std::move(shared);
    ++length_;
  }
  if (length_ < needed_) return {};
  return shared_;
}

}  // namespace evar::node
