#include "evar/node/device_candidate.hpp"

#include <cstdio>

namespace evar::node {

FrameAnalysis analyse_frame(const cv::Mat& image, const FrameView& view, const CandidateOptions& options) {
  geometry::SegmentationOptions s;
  s.device_width_px = geometry::device_shadow_width_px(view.view, options.device_diameter_mm);
  s.min_contrast = options.min_contrast;
  s.field_mask = options.field_mask;
  s.hidden_mask = options.hidden_mask;
  FrameAnalysis a;
  if (!(s.device_width_px > 0.5 && s.device_width_px < 100.0)) {
    a.reason = "the device's shadow would be " + std::to_string(s.device_width_px) + " px wide in this geometry";
    return a;
  }
  a.curve = geometry::segment_device(image, s);
  if (!a.curve.found) {
    a.reason = a.curve.reason;
  } else if (a.curve.confidence < options.min_confidence) {
    char why[96];
    std::snprintf(why, sizeof why, "device found with confidence %.2f (below %.2f)", a.curve.confidence,
                  options.min_confidence);
    a.reason = why;
  } else {
    a.candidate = true;
  }
  return a;
}

}  // namespace evar::node
