#pragma once
// The steps of segment_device (device_segmentation.cpp), in the order it takes them, each
// in a file of its own:
//   device_ridge.cpp          the ridge measure at the best of a few scales, in noise units
//   ridge_hysteresis.cpp      non-maximum suppression across the ridge, then hysteresis
//   ridge_paths.cpp           the band around the confident ridge and minimal paths in it
//   device_tip.cpp            the evidence along each path, and the device's tip
//   device_curve_verdict.cpp  the path trimmed to the device, measured and judged
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <queue>
#include <vector>

#include "evar/geometry/device_segmentation.hpp"

namespace evar::geometry::segmentation {

// The ridge measure at the best scale, with the across-ridge normal and the Newton offset
// from the pixel to the ridge centre along it.
struct Ridge {
  cv::Mat response;  // CV_32F, noise units
  cv::Mat nx, ny;    // CV_32F unit normal
  cv::Mat offset;    // CV_32F, px along the normal
  cv::Mat contrast;  // CV_32F, the top-hat attenuation (−log units): the device's Δp on its centreline
  cv::Mat attenuation;  // CV_32F, −log(I + 1), lightly smoothed: the background on either side
};

/// The ridge scales, px: the options' own, or 0.35, 0.5 and 0.7 device widths.
std::vector<double> scales_of(const SegmentationOptions& o);

/// The ridge measure of `intensity` (CV_32F) inside `inner`; zero outside it.
Ridge compute_ridge(const cv::Mat& intensity, const cv::Rect& inner, const SegmentationOptions& o);

/// `m` (CV_32F) at (x, y), bilinear; 0 where a neighbour is outside it.
inline float bilinear(const cv::Mat& m, float x, float y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= m.cols || y0 + 1 >= m.rows) return 0.0f;
  const float fx = x - static_cast<float>(x0), fy = y - static_cast<float>(y0);
  return (1 - fy) * ((1 - fx) * m.at<float>(y0, x0) + fx * m.at<float>(y0, x0 + 1)) +
         fy * ((1 - fx) * m.at<float>(y0 + 1, x0) + fx * m.at<float>(y0 + 1, x0 + 1));
}

/// Ridge pixels (CV_8U, 1 or 0) that are maxima across the ridge, above the low threshold,
/// in 8-connected chains of at least 12 that reach the high threshold somewhere.
cv::Mat confident_ridge_pixels(const Ridge& ridge, const cv::Rect& inner, const SegmentationOptions& o);

/// Minimal paths through the band: the inner field's pixels within gap_radius_px of a
/// confident one. A pixel costs 1 on a confident ridge and up to 31 on flat background
/// (crossing 10 px of background costs as much as following 300 px of wire); a step costs
/// the mean of its two pixels' costs. The band stays a rim inside the image, so a band
/// pixel's neighbours are all in the image. Pixels are indices y * width + x.
class RidgePaths {
 public:
  /// `searched` (CV_8U, or empty for all of `inner`): the pixels of `inner` the path may use.
  /// `field` (CV_8U, or empty): the field they lie in, holes (masked text) filled: its edge is
  /// a border of the field as `inner`'s is (an image intensifier's circle); a hole's is not.
  RidgePaths(const Ridge& ridge, const cv::Mat& confident, const cv::Rect& inner, const SegmentationOptions& o,
             const cv::Mat& searched = {}, const cv::Mat& field = {});

  /// Seeds every band pixel on the inner field's border (or the field's edge); false when
  /// there is none.
  bool seed_border();
  bool in_band(int q) const { return band_[static_cast<std::size_t>(q)] != 0; }
  /// Settles every band pixel reachable from the seeds, nearest first.
  void run_from(int root);
  void run();
  /// The search again from `root` only.
  void reroot(int root);

  int width() const { return W_; }
  const std::vector<int>& order() const { return order_; }  ///< settled pixels, parents before children
  int parent(int q) const { return parent_[static_cast<std::size_t>(q)]; }
  float distance(int q) const { return dist_[static_cast<std::size_t>(q)]; }
  std::size_t size() const { return dist_.size(); }

 private:
  void push(float d, int q);

  int W_, H_;
  cv::Rect inner_;
  cv::Mat searched_, field_;
  std::vector<std::uint8_t> band_;
  std::vector<float> band_cost_;
  std::vector<float> dist_;
  std::vector<int> parent_;
  std::vector<int> order_;
  // (distance, pixel) packed into one word that orders as the pair does (the bits of a
  // non-negative float order as the float): one integer compare per heap step.
  std::priority_queue<std::uint64_t, std::vector<std::uint64_t>, std::greater<>> heap_;
};

/// What the evidence along a path is judged on. Only confident pixels that look like a
/// line on the background count: the background 1.5 device widths to either side must
/// differ by less than 0.3 of the line's contrast (the rim of a bone sits on a step, a
/// wire does not).
struct PathEvidence {
  cv::Mat contrast_local;  ///< the ridge's contrast, largest within the device's width
  cv::Mat response_local;  ///< the ridge response, largest within the device's width
  cv::Mat line_like;       ///< confident pixels with the same background on both sides
  cv::Mat near_line;       ///< line_like, dilated by a pixel
  float side_px = 0.0f;    ///< 1.5 device widths
};
PathEvidence path_evidence(const Ridge& ridge, const cv::Mat& confident, const cv::Rect& inner,
                           const SegmentationOptions& o);
/// How much denser one side of the ridge through pixel (x, y) is than the other.
float side_step_at(const Ridge& ridge, const PathEvidence& e, int y, int x);

/// The tip: the line-like pixel (within the seed's radius, when there is a seed) with the
/// most evidence on its way to the root. Its buffers are kept for the next search.
class TipChooser {
 public:
  explicit TipChooser(std::size_t pixels);
  /// −1 when no pixel qualifies.
  int choose(const RidgePaths& paths, const PathEvidence& e, const SegmentationOptions& o);

 private:
  std::vector<float> score_, running_, running_contrast_;
};

/// Trims `path` (tip first, to the root) to the device, measures it into `result` (points,
/// length, gaps, response, contrast, side step, confidence) and judges it: `result.found`,
/// or `result.reason` saying why not. `k`: the grid's pixel in frame pixels.
void measure_and_judge(std::vector<int> path, bool border_reachable, const Ridge& ridge, const PathEvidence& e,
                       const SegmentationOptions& o, int k, DeviceCurve2D& result);

/// Resampled every `step` px and smoothed by a Gaussian of `sigma` px along arc length.
std::vector<Eigen::Vector2d> resample_and_smooth(const std::vector<Eigen::Vector2d>& pts, double step, double sigma);

}  // namespace evar::geometry::segmentation
