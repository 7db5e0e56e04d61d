#pragma once
// Where the detector's image lies in a C-arm's video output: the monitor's picture, which
// is what a box on the video out grabs, holds the fluoroscopy image scaled into a rectangle
// of the frame, turned in 90° steps and perhaps mirrored by the display settings, with text
// burned in around it (issue 31; docs/FORMATS.md, "Video mapping").
//
// Pixel positions are OpenCV's and the projection's: pixel (i, j) is centred at (i, j), so
// the image rectangle [x, y, w, h] covers video pixels x … x + w − 1 and y … y + h − 1,
// edges at x − ½ and x + w − ½. As DICOM XA's Field of View Rotation and Horizontal Flip,
// the detector image is turned first (clockwise as seen) and then mirrored left to right.
#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace evar::geometry {

struct PixelRect {
  double x = 0, y = 0, width = 0, height = 0;  ///< video pixels: first column, first row, size
};

enum class FieldShape { Rectangle, Circle };

/// The pinned object (`"format": "evarnode-video-mapping"`, version 1), in node.json and
/// the view geometry under "video_mapping", or a file of its own.
struct VideoMapping {
  int video_cols = 0, video_rows = 0;     ///< the grabbed frame's size (px)
  PixelRect image_rect;                   ///< where the detector image is shown in it
  bool mirror = false;                    ///< shown mirrored left to right (after turning)
  int rotation_deg = 0;                   ///< 0, 90, 180 or 270: turned clockwise as shown
  FieldShape field_shape = FieldShape::Rectangle;  ///< an image intensifier's is a circle
  std::vector<PixelRect> text_regions;    ///< burned-in text and graphics (video pixels)
};

/// The picture turned `rotation_deg` clockwise as seen, then mirrored left to right when
/// `mirror`, on offsets from its centre (x right, y down): a 2x2 matrix of 0 and ±1, the
/// linear part of a mapping before its scale. std::invalid_argument for a rotation that is
/// not 0, 90, 180 or 270.
Eigen::Matrix2d turn_and_mirror(int rotation_deg, bool mirror);

/// A mapping applied to a detector of `detector_cols` × `detector_rows` pixels: the
/// affine map both ways, as 2×3 matrices on pixel centres.
class VideoToDetector {
 public:
  /// std::invalid_argument when the mapping is invalid (validate_video_mapping) or the
  /// rectangle's shape is not the turned detector's (more than 2 % apart: a wrong rotation
  /// or rectangle; the display's pixels are square).
  VideoToDetector(const VideoMapping& mapping, int detector_cols, int detector_rows);

  Eigen::Vector2d to_video(const Eigen::Vector2d& detector_px) const;
  Eigen::Vector2d to_detector(const Eigen::Vector2d& video_px) const;
  /// video = A · [detector; 1]
  const Eigen::Matrix<double, 2, 3>& detector_to_video() const { return forward_; }
  const Eigen::Matrix<double, 2, 3>& video_to_detector() const { return inverse_; }
  int detector_cols() const { return detector_cols_; }
  int detector_rows() const { return detector_rows_; }
  int video_cols() const { return video_cols_; }
  int video_rows() const { return video_rows_; }
  /// Video pixels per detector pixel along a line (the square root of the area ratio; the
  /// two axes' scales differ by at most the 2 % the constructor allows).
  double video_px_per_detector_px() const;

 private:
  Eigen::Matrix<double, 2, 3> forward_, inverse_;
  int detector_cols_ = 0, detector_rows_ = 0, video_cols_ = 0, video_rows_ = 0;
};

/// "" when VideoToDetector takes the mapping for a detector of `detector_cols` ×
/// `detector_rows`, else its reason (the mapping's own problem, or a rectangle that is not the
/// turned detector's shape).
std::string video_mapping_fit_problem(const VideoMapping& mapping, int detector_cols, int detector_rows);

/// "" when the mapping is valid, else what is wrong, naming the field: sizes of 1 to 16384
/// px, the image rectangle and every text region inside the frame with a positive size,
/// the rotation a multiple of 90 in 0 … 270.
std::string video_mapping_problem(const VideoMapping& mapping);

/// The mapping from its JSON object; InputError "<source>: <field>: <what>" (the field
/// under `field_prefix`, e.g. "video_mapping.").
VideoMapping parse_video_mapping(const nlohmann::json& object, const std::filesystem::path& source,
                                 const std::string& field_prefix = "");
nlohmann::json video_mapping_json(const VideoMapping& mapping);

VideoMapping read_video_mapping(const std::filesystem::path& path);
void write_video_mapping(const std::filesystem::path& path, const VideoMapping& mapping);

}  // namespace evar::geometry
