#pragma once
// The ways a picture may be shown turned and mirrored against what a mapping says: the
// eight symmetries of a square picture (the four of a rectangle), as a video mapping and
// DICOM XA say them, turned clockwise as seen, then mirrored left to right, about the
// picture's centre. What node/picture_orientation.hpp tries a view's picture under.
#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "evar/geometry/video_mapping.hpp"

namespace evar::node {

struct PictureTurn {
  int rotation_deg = 0;  ///< 0, 90, 180 or 270
  bool mirror = false;
  bool operator==(const PictureTurn&) const = default;
};

/// "mirrored", "turned 90 degrees clockwise", "turned 180 degrees clockwise and mirrored",
/// "as it is" (plain ASCII: the status block draws no degree sign).
std::string turn_text(const PictureTurn& turn);

/// The turn on offsets from the picture's centre, x right and y down: a 2x2 matrix of 0
/// and ±1 (geometry::turn_and_mirror). std::invalid_argument for a rotation that is not 0,
/// 90, 180 or 270.
Eigen::Matrix2d turn_matrix(const PictureTurn& turn);

/// Where the points of a `cols` × `rows` picture lie when it is turned as said (pixel
/// centres, (0, 0) the first; the picture's centre stays). std::invalid_argument for a
/// rotation that is not 0, 90, 180 or 270, or a quarter turn of a picture that is not
/// square (it would not fill the same pixels).
std::vector<Eigen::Vector2d> turned_points(const std::vector<Eigen::Vector2d>& points_px, const PictureTurn& turn,
                                           int cols, int rows);

/// The picture turned as turned_points turns its points: a point p of `picture` lies at
/// turned_points({p}) in the result. Quarter turns swap the sides.
cv::Mat turned_image(const cv::Mat& picture, const PictureTurn& turn);

/// The turn that undoes `turn` (a quarter turn the other way; a mirror undoes itself, with
/// or without a turn).
PictureTurn inverse(const PictureTurn& turn);

/// The turns other than none that keep a picture's shape: 7 for a square, 3 otherwise.
std::vector<PictureTurn> other_turns(bool square);

/// A turn of the detector's picture as it shows on the video frame through `mapping`
/// (the mapping's own turn and mirror conjugate it: a mirror of the detector's columns is
/// an upside-down picture on a display that turns it by 90°).
PictureTurn turn_as_shown(const PictureTurn& detector_turn, const geometry::VideoMapping& mapping);

/// The video mapping under which a frame reads as `set` reads it turned by `missed`: the
/// same rectangle with the mirror and rotation_deg that make the difference, for a picture
/// of `cols` × `rows`. nullopt when no mirror and rotation do (a quarter turn of a picture
/// that is not square), or `set` does not fit such a picture.
std::optional<geometry::VideoMapping> mapping_with_turn(const geometry::VideoMapping& set, const PictureTurn& missed,
                                                        int cols, int rows);

}  // namespace evar::node
