#pragma once
// What a box on a C-arm's video output grabs (issue 31): the detector image as the C-arm's
// monitor shows it, scaled into its rectangle of the video frame, turned and mirrored by the
// display settings, black around it, an image intensifier's round field, and text burned
// into the frame's text regions (patient, angulation, frame counter).
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "evar/geometry/video_mapping.hpp"

namespace evar::sim {

/// The monitor's picture of `detector` (CV_16UC1, the mapping's detector size): a
/// `mapping.video_cols` × `mapping.video_rows` CV_16UC1 frame, 0 outside the image
/// rectangle (and outside the circle inscribed in it for FieldShape::Circle), each of
/// `text` drawn at full white in the text region of the same index (lines beyond the
/// regions are left out). std::invalid_argument when the mapping does not fit the detector.
cv::Mat monitor_picture(const cv::Mat& detector, const geometry::VideoMapping& mapping,
                        const std::vector<std::string>& text);

}  // namespace evar::sim
