#pragma once
// Whether a frame shows the device well enough to reconstruct from: the segmentation set
// up for the frame's view (the shadow width from the magnification and the pixel spacing)
// and a confidence floor.
#include <string>

#include <opencv2/core.hpp>

#include "evar/geometry/device_segmentation.hpp"
#include "evar/node/frame_view.hpp"

namespace evar::node {

struct CandidateOptions {
  double device_diameter_mm = 0.89;  ///< 0.035" guidewire
  /// Least attenuation contrast (−log units) of raw linear detector data; 0 for processed
  /// (log or windowed) video (geometry::SegmentationOptions::min_contrast).
  double min_contrast = 0.25;
  double min_confidence = 0.5;       ///< geometry::DeviceCurve2D::confidence
  /// Empty, or where the detector image shows the field and where graphics hide it
  /// (geometry::SegmentationOptions::field_mask, hidden_mask): set from a video mapping with
  /// an image intensifier's circle or text over the image.
  cv::Mat field_mask, hidden_mask;
};

struct FrameAnalysis {
  bool candidate = false;
  std::string reason;              ///< why not, when not
  geometry::DeviceCurve2D curve;
};

/// Segments `image` (CV_8UC1 or CV_16UC1). Never throws on image content.
FrameAnalysis analyse_frame(const cv::Mat& image, const FrameView& view, const CandidateOptions& options);

}  // namespace evar::node
