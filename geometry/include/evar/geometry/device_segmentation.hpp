#pragma once
// Finds a guidewire or catheter in an uncontrasted fluoroscopy frame and returns it as an
// ordered, sub-pixel polyline from the tip to the image (field) border.
//
//   1. attenuation image p = −log(I + 1) (a wire adds the same Δp over bright and dark
//      background), its white top-hat with a square 2.5x the device's width (background and
//      wider structures removed), and the exposed field (collimator shutters found from
//      row and column profiles);
//   2. multi-scale Hessian ridge measure for thin attenuating curves: σ²·(−λ₂) where λ₂ < 0
//      is the across-ridge eigenvalue, damped for blobs (|λ₁/λ₂|) and for the flanks of
//      step edges (the Newton offset −∂ₙp/λ₂ to the ridge centre is about σ there, under
//      half a pixel on a ridge); divided by the local noise level of the measure;
//   3. non-maximum suppression across the ridge and hysteresis (6 and 3 noise units);
//   4. a minimal path from the field border through a cost that is 1 on confident ridge and
//      31 on background, in a band around the confident ridge pixels, so gaps and
//      crossings are bridged; the tip is the confident pixel whose path to the border
//      collects the most ridge evidence (gaps and corners sharper than 50° over 8 px count
//      against it: a wire bends gently, a path hopping from a bony rim onto it does not),
//      or the best one near a given seed;
//   5. sub-pixel centres (the Newton offset across the ridge), resampling and smoothing
//      along arc length;
//   6. checks that it is a device: its median contrast (top-hat attenuation) is at least
//      `min_contrast`, and the background on its two sides differs by less than 0.3 of that
//      contrast (the edge of a bone is a step with a rim; a wire lies on the background).
#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace evar::geometry {

struct SegmentationOptions {
  /// Expected width of the device's shadow (px): its diameter × magnification / pixel
  /// spacing (a 0.89 mm guidewire at magnification 1.5 on 0.3 mm pixels: 4.5 px). Sets the
  /// ridge scales (0.35, 0.5 and 0.7 of it) and the top-hat square (2.5 times it), which
  /// removes everything wider: bodies, rims and edges of bone wider than the device.
  double device_width_px = 3.0;
  std::vector<double> scales_px;  ///< Gaussian σ of the ridge measure; empty = from device_width_px
  double high_threshold = 6.0;    ///< hysteresis, in noise units of the measure
  double low_threshold = 3.0;
  double min_length_px = 30.0;    ///< shorter confident structures are not a device
  /// Least attenuation contrast Δp (−log units of raw, linear detector data) of a device
  /// over its background: metal wires 0.3–0.8, bony lines about 0.1–0.2. Set 0 for
  /// processed (log or windowed) video where the scale is unknown.
  double min_contrast = 0.25;
  double gap_radius_px = 30.0;    ///< how far the minimal path may leave confident pixels
  std::optional<Eigen::Vector2d> seed_px;  ///< a click on or near the tip
  double seed_radius_px = 20.0;
  double sample_step_px = 1.0;    ///< spacing of the output points
  double smoothing_px = 2.0;      ///< Gaussian σ along arc length
  /// Empty, or CV_8U of the image's size: where the image shows the detector's field (an
  /// image intensifier's circle; video_frame.hpp's detector_field_mask). Only there is a
  /// device searched for, and its edge is a border of the field as the shutters' are (the
  /// same rim kept clear): a device may leave the field there.
  cv::Mat field_mask;
  /// Empty, or CV_8U of the image's size: graphics burned in over the field (text, a ruler;
  /// detector_text_mask). Not searched (nor a rim round them), and no way out of the field.
  cv::Mat hidden_mask;
};

struct DeviceCurve2D {
  bool found = false;
  std::string reason;                    ///< why nothing was found (empty when found)
  std::vector<Eigen::Vector2d> points;   ///< tip first, sub-pixel (px; (0,0) = centre of the top-left pixel)
  double confidence = 0.0;               ///< (1 − gap_fraction) · min(1, median response / high threshold)
  double length_px = 0.0;
  double gap_fraction = 0.0;             ///< share of the path below the low threshold (bridged)
  double median_response = 0.0;          ///< along the path, in noise units
  double contrast = 0.0;                 ///< median attenuation of the curve over its background (−log units)
  double side_step = 0.0;                ///< median difference of the background on its two sides (−log units)
  bool reaches_border = false;           ///< the path ends at the border of the exposed field
  cv::Rect field;                        ///< the exposed field found
  double ridge_ms = 0.0;                 ///< attenuation, top-hat, Hessian scales, noise level
  double path_ms = 0.0;                  ///< suppression, hysteresis, minimal path, checks
};

/// `image`: CV_8UC1 or CV_16UC1 (dark = attenuating) or CV_32FC1 intensities.
/// Never throws on image content; std::invalid_argument for another type or empty image.
DeviceCurve2D segment_device(const cv::Mat& image, const SegmentationOptions& options = {});

}  // namespace evar::geometry
