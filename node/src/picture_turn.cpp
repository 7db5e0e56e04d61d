#include "evar/node/picture_turn.hpp"

#include <cmath>
#include <stdexcept>

#include <opencv2/core.hpp>

namespace evar::node {

std::string turn_text(const PictureTurn& t) {
  if (t.rotation_deg == 0) return t.mirror ? "mirrored" : "as it is";
  return "turned " + std::to_string(t.rotation_deg) + " degrees clockwise" + (t.mirror ? " and mirrored" : "");
}

Eigen::Matrix2d turn_matrix(const PictureTurn& t) {
  if (t.rotation_deg % 90 != 0 || t.rotation_deg < 0 || t.rotation_deg > 270)
    throw std::invalid_argument("picture turn: rotation " + std::to_string(t.rotation_deg) +
                                " degrees is not 0, 90, 180 or 270");
  // A clockwise quarter turn as seen takes (x, y) to (−y, x); the mirror takes x to −x.
  Eigen::Matrix2d Q = Eigen::Matrix2d::Identity();
  const Eigen::Matrix2d quarter{{0.0, -1.0}, {1.0, 0.0}};
  for (int k = 0; k < t.rotation_deg / 90; ++k) Q = quarter * Q;
  if (t.mirror) Q.row(0) *= -1.0;
  return Q;
}

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
  const Eigen::Matrix2d S = L * turn_matrix(detector_turn) * L.transpose();  // L is orthogonal
  for (const int r : {0, 90, 180, 270})
    for (const bool mirror : {false, true})
      if ((turn_matrix({r, mirror}) - S).cwiseAbs().maxCoeff() < 1e-9) return {r, mirror};
  throw std::logic_error("turn_as_shown: a turn conjugated by a turn is not a turn");
}

std::optional<geometry::VideoMapping> mapping_with_turn(const geometry::VideoMapping& set, const PictureTurn& missed,
                                                        int cols, int rows) {
  if (!geometry::video_mapping_fit_problem(set, cols, rows).empty()) return std::nullopt;
  if (missed.rotation_deg % 180 != 0 && cols != rows) return std::nullopt;
  const geometry::VideoToDetector as_set(set, cols, rows);
  // Three corners of the rectangle (pixel centres) fix an affine map.
  const auto& r = set.image_rect;
  const std::vector<Eigen::Vector2d> video{{r.x, r.y}, {r.x + r.width - 1, r.y}, {r.x, r.y + r.height - 1}};
  std::vector<Eigen::Vector2d> read;
  for (const auto& v : video) read.push_back(as_set.to_detector(v));
  const auto wanted = turned_points(read, missed, cols, rows);
  for (const int rotation : {0, 90, 180, 270})
    for (const bool mirror : {false, true}) {
      geometry::VideoMapping m = set;
      m.rotation_deg = rotation;
      m.mirror = mirror;
      if (!geometry::video_mapping_fit_problem(m, cols, rows).empty()) continue;
      const geometry::VideoToDetector candidate(m, cols, rows);
      bool same = true;
      for (std::size_t k = 0; k < video.size(); ++k) same = same && (candidate.to_detector(video[k]) - wanted[k]).norm() < 1e-6;
      if (same) return m;
    }
  return std::nullopt;
}

}  // namespace evar::node
