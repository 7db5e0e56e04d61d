#pragma once
// A C-arm's zoom (magnification, field-of-view) modes: each shows a part of the detector in
// an image of its own pixels, as DICOM XA describes a field of view (PS3.3 C.8.7.3 and
// C.8.19.6): Field of View Shape (0018,1147), Dimension(s) (0018,1149), Origin (0018,7030),
// Rotation (0018,7032), Horizontal Flip (0018,7034), Imager Pixel Spacing (0018,1164), and
// the image's Rows and Columns. The C-arm link says which mode a frame was taken in
// (CArmPose::zoom_mode), or node.json fixes one (docs/FORMATS.md, "Zoom modes").
//
// The detector (DetectorSpec) is then the physical one: its pixels are the detector
// elements, its centre on the central ray. A mode's image pixel (i, j), centred at (i, j) as
// everywhere, lies at the detector position
//   x_mm = c_x + (i − (cols − 1)/2) · col_spacing,   y_mm = c_y + (j − (rows − 1)/2) · row_spacing
// from the central ray (x along the detector's columns, y down its rows), c the field's
// centre: the detector's centre unless the origin places it elsewhere. The projection onto
// the mode's image is the detector's with K's principal point moved by −c / spacing.
//
// The image as the C-arm delivers it is the field turned (clockwise as seen) and then
// mirrored left to right, as the video mapping turns and mirrors the image it shows; the
// projection lands on the field before both (frame_mapping()).
#include <Eigen/Core>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/detector.hpp"
#include "evar/geometry/video_mapping.hpp"

namespace evar::geometry {

struct ZoomMode {
  int number = 0;                 ///< as the C-arm link numbers it: 1-255
  std::string name;               ///< what the C-arm calls it, e.g. "48 cm" or "MAG 2"
  FieldShape shape = FieldShape::Rectangle;  ///< DICOM RECTANGLE, or ROUND (an image intensifier's)
  double height_mm = 0, width_mm = 0;        ///< the field at the detector (ROUND: the diameter both)
  int cols = 0, rows = 0;                    ///< the image's pixels
  double row_spacing_mm = 0, col_spacing_mm = 0;  ///< Imager Pixel Spacing, at the detector
  /// Field of View Origin: the rows and columns of detector elements from the detector's
  /// top-left corner to the field's; unset: the field is centred on the detector.
  std::optional<Eigen::Vector2d> origin_rows_cols;
  int rotation_deg = 0;           ///< 0, 90, 180 or 270: the field turned clockwise in the image
  bool horizontal_flip = false;   ///< then mirrored left to right
};

/// A rectangular field centred on the detector, unturned: `cols` × `rows` square pixels of
/// `spacing_mm`, its dimensions theirs (what most flat-detector C-arms' modes are).
ZoomMode centred_zoom_mode(int number, std::string name, int cols, int rows, double spacing_mm);

/// The mode's image as a detector of its own: its pixels and spacings.
DetectorSpec image_detector(const ZoomMode& mode);

/// Where the field's centre lies on the detector, from the central ray (mm; x along the
/// columns, y down the rows).
Eigen::Vector2d field_centre_mm(const DetectorSpec& detector, const ZoomMode& mode);

/// The view of an angulation and distances in the mode: the mode's pixels and spacings, and
/// the projection matrix onto its field (principal point where the central ray meets it).
CArmView zoom_view(const DetectorSpec& detector, const ZoomMode& mode, double primary_deg, double secondary_deg,
                   double sid_mm, double sod_mm);

/// How the frames hold the mode's field: the display's mapping (the monitor's picture of
/// the image the C-arm delivers) composed with the mode's rotation and flip; without a
/// display mapping, the delivered image itself when the mode turns, flips or is round (the
/// frame is then all image: the rectangle is the whole frame); nullopt when the frames are
/// the field's pixels as they are.
std::optional<VideoMapping> frame_mapping(const std::optional<VideoMapping>& display, const ZoomMode& mode);

/// The size (cols, rows) of the frames that hold the mode's image: the display mapping's
/// video size, else the image as delivered (turned as the mode turns it).
std::pair<int, int> frame_size_px(const std::optional<VideoMapping>& display, const ZoomMode& mode);

/// "" when the mode is usable on `detector`, else what is wrong, naming the field: number
/// 1-255, a name, 1-16384 pixels each way, positive spacings, the dimensions those of the
/// pixels (within two pixels), a ROUND field square, rotation in 90° steps, the field on
/// the detector (within one detector element).
std::string zoom_mode_problem(const ZoomMode& mode, const DetectorSpec& detector);

/// A "zoom_modes" array (node.json, session.json): each mode parsed and checked against
/// `detector`, the numbers distinct. InputError "<source>: <prefix>zoom_modes[k].<field>: <what>".
std::vector<ZoomMode> parse_zoom_modes(const nlohmann::json& array, const DetectorSpec& detector,
                                       const std::filesystem::path& source, const std::string& prefix = "");
nlohmann::json zoom_modes_json(const std::vector<ZoomMode>& modes);

/// The mode numbered `number`, or null.
const ZoomMode* find_zoom_mode(const std::vector<ZoomMode>& modes, int number);

}  // namespace evar::geometry
