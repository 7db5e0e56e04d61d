#pragma once
// Frames of a test session: 16-bit ramps whose every pixel is known, so a test can check
// that frames arrive whole, in order and unaltered through a transport or a recording.
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "evar/session/session.hpp"

namespace evar::test {

/// Pixel (x, y) of frame k is per_frame·k + per_row·y + per_col·x + offset.
struct Ramp {
  int per_frame = 0, per_row = 0, per_col = 0, offset = 0;
};

/// Appends n fluoroscopy frames "f<k>.png" to the session, the first at 1 s and then one
/// every period_ns, of the session's detector size; returns their images.
inline std::vector<cv::Mat> add_ramp_frames(session::Session& s, int n, std::int64_t period_ns, const Ramp& r) {
  std::vector<cv::Mat> images;
  for (int k = 0; k < n; ++k) {
    std::string name = "f";  // in steps: g++ 12 warns falsely (-Wrestrict) on "f" + std::string
    name += std::to_string(k) + ".png";
    s.frames.push_back({k, 1'000'000'000LL + k * period_ns, "fluoro", name});
    cv::Mat img(s.detector.rows, s.detector.cols, CV_16UC1);
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x)
        img.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(r.per_frame * k + r.per_row * y + r.per_col * x + r.offset);
    images.push_back(img);
  }
  return images;
}

}  // namespace evar::test
