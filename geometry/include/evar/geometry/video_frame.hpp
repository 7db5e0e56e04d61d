#pragma once
// A video-out frame and the detector behind it (issue 31): the detector image read back out
// of the frame's image rectangle, and a detector projection carried onto the frame, so the
// analysis works on detector pixels and the overlay is drawn where the monitor shows them.
#include <opencv2/core/mat.hpp>
#include <string>

#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/video_mapping.hpp"

namespace evar::geometry {

/// The detector image (detector_cols × detector_rows, the frame's type) resampled out of a
/// video-out frame: turned and mirrored back, bilinear (the frame's edge repeated past it).
/// std::invalid_argument when the frame is not the mapping's video size.
cv::Mat detector_image(const cv::Mat& video_frame, const VideoToDetector& map);

/// Where the detector image shows the field (CV_8U, the detector's size, 255 there): inside
/// an image intensifier's circle (the one inscribed in the image rectangle). Empty for a
/// rectangle: the whole detector image.
cv::Mat detector_field_mask(const VideoMapping& mapping, const VideoToDetector& map);

/// Where burned-in text regions cover the detector image (CV_8U, 255 there). Empty when none
/// lies over it.
cv::Mat detector_text_mask(const VideoMapping& mapping, const VideoToDetector& map);

/// Why a detector image read out of a video-out frame is not live fluoroscopy, or "" when
/// nothing says so: the field (where `field_mask` is set, all of it when empty) shows one
/// flat grey (no image on the monitor), or more than 40 % of it is one grey level other
/// than the darkest present and a full-scale white (a menu, a dialog or a graphic over the
/// image; a windowed display clips to black and white, a detector saturates at 2^n − 1).
/// 8- or 16-bit grey.
std::string not_fluoroscopy(const cv::Mat& detector_image, const cv::Mat& field_mask = {});

/// The projection onto the video frame: [A; 0 0 1] · P, A the detector-to-video affine.
ProjectionMatrix projection_on_video(const ProjectionMatrix& P_detector, const VideoToDetector& map);

}  // namespace evar::geometry
