#pragma once
// The roadmap drawing's internals (mesh_preview.hpp is its public face), by file:
//   roadmap_drawing.cpp     the checks, draw_overlay (fills, then outlines, lines, markers), the Image type
//   silhouette.cpp          the union of a layer's projected triangles, sampled finer than the image
//   annotations.cpp         polylines, markers, text and their labels' placement
//   comparison_picture.cpp  the two-panel AP + lateral picture with its title, legend and scale bars
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <span>
#include <string>
#include <vector>

#include "evar/overlay/mesh_preview.hpp"

namespace evar::overlay::drawing {

// Sub-pixel drawing: OpenCV takes fixed-point coordinates with this many fraction bits.
constexpr int kShift = 4;
constexpr double kFixedOne = 1 << kShift;
// Projected coordinates are clamped to this many pixels so fixed-point values stay far
// from int overflow; only a degenerate (near-source) projection gets anywhere near it.
constexpr double kMaxCoordPx = 1e5;
constexpr int kMaxPanelPx = 8192;

inline const Bgr kHalo{8, 8, 8};
inline const Bgr kText{235, 235, 235};
inline const Bgr kDimText{165, 160, 155};
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr int kTitleFont = cv::FONT_HERSHEY_DUPLEX;

inline cv::Scalar scalar(Bgr c) { return {static_cast<double>(c.b), static_cast<double>(c.g), static_cast<double>(c.r)}; }

// Image coordinates (px) -> OpenCV fixed-point drawing coordinates.
inline cv::Point fixed(const Eigen::Vector2d& uv) {
  const auto one = [](double x) {
    return static_cast<int>(std::lround(std::clamp(x, -kMaxCoordPx, kMaxCoordPx) * kFixedOne));
  };
  return {one(uv.x()), one(uv.y())};
}

/// Throws std::invalid_argument naming the layer, polyline or marker that cannot be drawn.
void check_overlay(const Overlay& overlay);
void check_options(const DrawOptions& options);

/// Draws `overlay` into every image (all of one size), rasterising the silhouettes and
/// tracing their outlines once.
void draw_overlay(std::span<cv::Mat> images, const ViewProjection& view, const Overlay& overlay, const DrawOptions& options);
void draw_overlay(cv::Mat& image, const ViewProjection& view, const Overlay& overlay, const DrawOptions& options);

// A mask of samples covering part of the image's sample grid: the image pixels `pixels`,
// k x k samples each; sample (x, y) of the grid is mask(y - origin.y, x - origin.x) with
// origin = k · pixels.tl(), and the grid beyond the mask is empty.
struct SampleMask {
  cv::Rect pixels;
  cv::Point origin;  ///< in samples
  cv::Mat1b mask;
};

/// The union of the layer's projected triangles, sampled `supersample` times finer than
/// `size` along each axis, over the image pixels its bounding box touches.
SampleMask silhouette(const ViewProjection& view, const MeshLayer& layer, cv::Size size, int supersample);
/// image = image * (1 - a) + colour * a with a = alpha * coverage / 255, per pixel.
void blend(cv::Mat& image, const cv::Mat1b& coverage, Bgr colour, double alpha);
/// The mask's boundaries (outer and holes) as fixed-point polylines in image pixels.
std::vector<std::vector<cv::Point>> outline(const SampleMask& grid, int supersample);

/// The outlines (traced once by the caller), the polylines and the labelled markers.
void draw_lines_and_markers(cv::Mat& image, const ViewProjection& view, const Overlay& overlay,
                            const std::vector<std::vector<std::vector<cv::Point>>>& outlines, const DrawOptions& options);
/// A ring (hollow) or a disc (filled) with a dark halo, centred at a fixed-point position.
void draw_marker_shape(cv::Mat& image, cv::Point centre_fixed, int radius_px, Bgr colour, bool filled);
/// Text with a dark halo; `origin` is the baseline start (OpenCV's putText convention).
void draw_text(cv::Mat& image, const std::string& text, cv::Point origin, int font, double scale, Bgr colour,
               int thickness = 1);
cv::Size text_size(const std::string& text, int font, double scale, int thickness, int* baseline = nullptr);

}  // namespace evar::overlay::drawing
