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

/// A 640 x 512 monitor showing a square image in [100, 8, 480, 480] (a 384 px detector 1.25
/// times enlarged), turned and mirrored as given, with four lines of text left and right of it.
inline geometry::VideoMapping square_image_monitor(int rotation_deg, bool mirror) {
  geometry::VideoMapping m;
  m.video_cols = 640;
  m.video_rows = 512;
  m.image_rect = {100, 8, 480, 480};
  m.rotation_deg = rotation_deg;
  m.mirror = mirror;
  m.text_regions = {{4, 4, 90, 20}, {4, 30, 90, 20}, {584, 4, 52, 20}, {584, 30, 52, 20}};
  return m;
}

}  // namespace evar::test
