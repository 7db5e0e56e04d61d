#pragma once
// Where the fluoroscopy image lies in frames grabbed from a C-arm's video output (issue 31,
// `evarnode calibrate-video`): the image area, its shape (a flat detector's rectangle or an
// image intensifier's circle) and the burned-in text around it, found from a few frames.
//
// The image area is what is not black in some frame, once thin strokes (text, rulers,
// cross-hairs) are opened away: the largest such region, its holes filled. Its bounding box
// is the image rectangle; a region filling less than 7/8 of it (π/4 for a circle) is round.
// Text is what is not black outside it, letters merged into lines; on the image, what is
// bright, thin and the same in every frame while the X-ray image's noise changes.
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "evar/geometry/video_mapping.hpp"

namespace evar::geometry {

struct VideoArea {
  int video_cols = 0, video_rows = 0;
  PixelRect image_rect;                 ///< video pixels, as in VideoMapping
  FieldShape field_shape = FieldShape::Rectangle;
  double fill = 0.0;                    ///< the image region's share of its rectangle
  std::vector<PixelRect> text_regions;  ///< burned-in text and graphics, outside the image and on it
  /// Whether graphics burned into the image itself were looked for: they are what never
  /// changes across the frames, so it takes two or more frames of live fluoroscopy that
  /// differ over at least half the image (`still_share` of it did not change at all).
  bool image_text_searched = false;
  double still_share = 1.0;
  double black_level = 0.0, threshold = 0.0;  ///< grey levels: the darkest, and "not black" above
};

/// From frames of one video output (8- or 16-bit grey, or BGR; all of one size).
/// std::invalid_argument when there are none, they differ in size, or nothing but black is
/// found (naming what was seen).
VideoArea find_video_area(const std::vector<cv::Mat>& frames);

/// Whether a grabbed frame still shows its image where `mapping` says (the node's check that
/// the mapping fits, issue 31): "" when it does or the frame cannot tell (nothing but black:
/// the beam off, no picture), else what does not fit, e.g. "the image area reaches 8 px left
/// of the mapping's image rectangle (found [92, 8, 480, 480], mapped [100, 8, 480, 480])".
/// Only image content past the mapped rectangle by more than `tolerance_px` counts: a picture
/// smaller than the rectangle may be collimator shutters closed over its edges.
std::string video_mapping_misfit(const cv::Mat& frame, const VideoMapping& mapping, double tolerance_px = 3.0);

/// The mapping the area proposes, with the display's turn and mirror (which the frames do not
/// show) as the operator gives them.
VideoMapping proposed_mapping(const VideoArea& area, int rotation_deg, bool mirror);

}  // namespace evar::geometry
