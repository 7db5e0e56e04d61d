#pragma once
// The monitor's picture of a detector frame, made as a C-arm's display makes it, with
// OpenCV's own operations and independently of evarnode's video mapping: turned clockwise,
// mirrored left to right, resized into the (whole-pixel) rectangle, black around it.
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "evar/geometry/video_mapping.hpp"

namespace evar::test {

inline cv::Mat shown_on_monitor(const cv::Mat& detector, const geometry::VideoMapping& m) {
  // Fresh outputs: OpenCV writes into a destination that shares the input's buffer.
  cv::Mat turned;
  if (m.rotation_deg == 90) cv::rotate(detector, turned, cv::ROTATE_90_CLOCKWISE);
  else if (m.rotation_deg == 180) cv::rotate(detector, turned, cv::ROTATE_180);
  else if (m.rotation_deg == 270) cv::rotate(detector, turned, cv::ROTATE_90_COUNTERCLOCKWISE);
  else turned = detector;
  cv::Mat mirrored;
  if (m.mirror) cv::flip(turned, mirrored, 1);
  else mirrored = turned;
  const cv::Rect rect(static_cast<int>(m.image_rect.x), static_cast<int>(m.image_rect.y),
                      static_cast<int>(m.image_rect.width), static_cast<int>(m.image_rect.height));
  cv::Mat resized;
  cv::resize(mirrored, resized, rect.size(), 0, 0, cv::INTER_LINEAR);
  cv::Mat frame(m.video_rows, m.video_cols, detector.type(), cv::Scalar(0));
  resized.copyTo(frame(rect));
  return frame;
}

}  // namespace evar::test
