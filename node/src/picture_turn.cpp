#include "evar/node/picture_turn.hpp"

#include <cmath>
#include <stdexcept>

#include <opencv2/core.hpp>

namespace evar::node {

std::string turn_text(const PictureTurn& t) {
  if (t.rotation_deg == 0) return t.mirror ? "mirrored" : "as it is";
  return "turned " + std::to_string(t.rotation_deg) + " degrees clockwise" + (t.mirror ? " and mirrored" : "");
}

Eigen::Matrix2d turn_matrix(const PictureTurn& t) { return geometry::turn_and_mirror(t.rotation_deg, t.mirror); }

namespace {

// The turn whose matrix is Q (a product of turn matrices).
PictureTurn turn_of(const Eigen::Matrix2d& Q) {
  for (const int r : {0, 90, 180, 270})
    for (const bool mirror : {false, true})
      if ((turn_matrix({r, mirror}) - Q).cwiseAbs().maxCoeff() < 1e-9) return {r, mirror};
  throw std::logic_error("picture turn: a product of turns that is not a turn");
}

}  // namespace

std::vector<Eigen::Vector2d> turned_points(const std::vector<Eigen::Vector2d>& points_px, const PictureTurn& t,
                                           int cols, int rows) {
  const Eigen::Matrix2d Q = turn_matrix(t);
  if (t.rotation_deg % 180 != 0 && cols != rows)
    throw std::invalid_argument("turned_points: a quarter turn of a " + std::to_string(cols) + " x " +
                                std::to_string(rows) + " picture does not fill its pixels");
  const Eigen::Vector2d centre(0.5 * (cols - 1), 0.5 * (rows - 1));
  std::vector<Eigen::Vector2d> out;
  out.reserve(points_px.size());
  for (const auto& p : points_px) out.push_back(centre + Q * (p - centre));
  return out;
}

cv::Mat turned_image(const cv::Mat& picture, const PictureTurn& t) {
  turn_matrix(t);  // a rotation it knows
  cv::Mat turned;
  if (t.rotation_deg == 90) cv::rotate(picture, turned, cv::ROTATE_90_CLOCKWISE);
  else if (t.rotation_deg == 180) cv::rotate(picture, turned, cv::ROTATE_180);
  else if (t.rotation_deg == 270) cv::rotate(picture, turned, cv::ROTATE_90_COUNTERCLOCKWISE);
  else turned = picture.clone();
  if (!t.mirror) return turned;
  cv::Mat mirrored;
  cv::flip(turned, mirrored, 1);
  return mirrored;
}

PictureTurn inverse(const PictureTurn& t) {
  turn_matrix(t);  // a rotation it knows
  return t.mirror ? t : PictureTurn{(360 - t.rotation_deg) % 360, false};
}

std::vector<PictureTurn> other_turns(bool square) {
  std::vector<PictureTurn> out;
  for (int r = 0; r < 360; r += square ? 90 : 180)
    for (const bool mirror : {false, true})
      if (r != 0 || mirror) out.push_back({r, mirror});
  return out;
}

PictureTurn turn_as_shown(const PictureTurn& detector_turn, const geometry::VideoMapping& mapping) {
  // The mapping shows detector offsets d at L·d (times its scale), L its turn and mirror.
  const Eigen::Matrix2d L = turn_matrix({mapping.rotation_deg, mapping.mirror});
  return turn_of(L * turn_matrix(detector_turn) * L.transpose());  // L is orthogonal
}

std::optional<geometry::VideoMapping> mapping_with_turn(const geometry::VideoMapping& set, const PictureTurn& missed,
                                                        int cols, int rows) {
  // The node reads d = F⁻¹(v) and the picture is T(d): the display's F' = F ∘ T⁻¹, whose
  // turn and mirror are L·Qᵀ (the rectangle stays).
  const PictureTurn fixed =
      turn_of(turn_matrix({set.rotation_deg, set.mirror}) * turn_matrix(missed).transpose());
  geometry::VideoMapping m = set;
  m.rotation_deg = fixed.rotation_deg;
  m.mirror = fixed.mirror;
  if (!geometry::video_mapping_fit_problem(set, cols, rows).empty() ||
      !geometry::video_mapping_fit_problem(m, cols, rows).empty())
    return std::nullopt;
  return m;
}

}  // namespace evar::node
