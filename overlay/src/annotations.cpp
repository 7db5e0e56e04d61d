#include <string>
#include <vector>

#include "drawing.hpp"

namespace evar::overlay::drawing {

// Text with a dark halo; `origin` is the baseline start (OpenCV's putText convention).
void draw_text(cv::Mat& image, const std::string& text, cv::Point origin, int font, double scale, Bgr colour,
               int thickness) {
  cv::putText(image, text, origin, font, scale, scalar(kHalo), thickness + 3, cv::LINE_AA);
  cv::putText(image, text, origin, font, scale, scalar(colour), thickness, cv::LINE_AA);
}

cv::Size text_size(const std::string& text, int font, double scale, int thickness, int* baseline) {
  int base = 0;
  const cv::Size size = cv::getTextSize(text, font, scale, thickness, &base);
  if (baseline) *baseline = base;
  return size;
}

void draw_marker_shape(cv::Mat& image, cv::Point centre_fixed, int radius_px, Bgr colour, bool filled) {
  const int r = radius_px << kShift;
  if (filled) {
    cv::circle(image, centre_fixed, r + static_cast<int>(kFixedOne), scalar(kHalo), cv::FILLED, cv::LINE_AA, kShift);
    cv::circle(image, centre_fixed, r, scalar(colour), cv::FILLED, cv::LINE_AA, kShift);
  } else {
    cv::circle(image, centre_fixed, r, scalar(kHalo), 4, cv::LINE_AA, kShift);
    cv::circle(image, centre_fixed, r, scalar(colour), 2, cv::LINE_AA, kShift);
  }
}

namespace {

// Projected polyline pieces (fixed point), split where a point cannot be projected.
std::vector<std::vector<cv::Point>> projected_pieces(const ViewProjection& view, const geometry::Polyline& points) {
  std::vector<std::vector<cv::Point>> pieces(1);
  for (const auto& p : points) {
    if (view.depth(p) > view.near_depth()) {
      pieces.back().push_back(fixed(view.project(p)));
    } else if (!pieces.back().empty()) {
      pieces.emplace_back();
    }
  }
  std::erase_if(pieces, [](const auto& piece) { return piece.size() < 2; });
  return pieces;
}

void draw_polyline(cv::Mat& image, const ViewProjection& view, const PolylineLayer& line) {
  const auto pieces = projected_pieces(view, line.points);
  if (pieces.empty()) return;
  // A dark halo keeps a thin bright line readable over fills and bright fluoroscopy.
  if (line.thickness_px >= 2)
    cv::polylines(image, pieces, false, scalar(kHalo), line.thickness_px + 2, cv::LINE_AA, kShift);
  cv::polylines(image, pieces, false, scalar(line.colour), line.thickness_px, cv::LINE_AA, kShift);
}


// Places labels beside their markers, on the side away from the image centre (outside the
// vessels, usually): first at the marker's height, pushed sideways past other markers,
// then a line lower or higher at a time until it overlaps no marker and no earlier label.
class LabelPlacer {
 public:
  LabelPlacer(cv::Size image, double font_scale) : image_(image), scale_(font_scale) {}

  /// Marks a marker's footprint so that no label covers it.
  void block(cv::Point2d centre, int radius_px) {
    const int r = radius_px + 2;
    taken_.emplace_back(static_cast<int>(std::lround(centre.x)) - r, static_cast<int>(std::lround(centre.y)) - r,
                        2 * r + 1, 2 * r + 1);
  }

  void place(cv::Mat& image, const std::string& text, cv::Point2d anchor, int radius_px, Bgr colour) {
    int baseline = 0;
    const cv::Size size = text_size(text, kFont, scale_, 1, &baseline);
    const bool right = anchor.x >= 0.5 * (image_.width - 1);
    const int ax = static_cast<int>(std::lround(anchor.x)), ay = static_cast<int>(std::lround(anchor.y));
    const int step = size.height + baseline + 2;
    cv::Rect box;
    bool free = false;
    for (int line = 0; line < 13 && !free; ++line) {
      const int k = (line + 1) / 2 * (line % 2 == 1 ? 1 : -1);  // 0, +1, -1, +2, -2, ... lines
      for (int push = 0; push < 3 && !free; ++push) {
        const int gap = radius_px + 4 + push * (2 * radius_px + 4);
        const int x = std::clamp(right ? ax + gap : ax - gap - size.width, 2,
                                 std::max(2, image_.width - size.width - 2));
        box = cv::Rect(x, ay - size.height / 2 + k * step - 1, size.width, size.height + baseline + 2);
        free = std::none_of(taken_.begin(), taken_.end(), [&](const cv::Rect& r) { return (r & box).area() > 0; });
      }
    }
    taken_.push_back(box);
    draw_text(image, text, {box.x, box.y + 1 + size.height}, kFont, scale_, colour);
  }

 private:
  cv::Size image_;
  double scale_;
  std::vector<cv::Rect> taken_;
};

}  // namespace

// The outlines (traced once by the caller), the polylines and the labelled markers.
void draw_lines_and_markers(cv::Mat& image, const ViewProjection& view, const Overlay& overlay,
                            const std::vector<std::vector<std::vector<cv::Point>>>& outlines, const DrawOptions& options) {
  for (std::size_t l = 0; l < overlay.layers.size(); ++l) {
    const MeshLayer& layer = overlay.layers[l];
    if (!layer.outline) continue;
    cv::polylines(image, outlines[l], true, scalar(layer.colour), layer.outline_px, cv::LINE_AA, kShift);
  }
  for (const PolylineLayer& line : overlay.polylines) draw_polyline(image, view, line);

  struct Visible {
    const Marker* marker;
    cv::Point2d uv;  // clamped like every drawn coordinate
  };
  std::vector<Visible> visible;
  for (const Marker& marker : overlay.markers) {
    if (!(view.depth(marker.position_lps) > view.near_depth())) continue;
    const Eigen::Vector2d uv = view.project(marker.position_lps);
    visible.push_back({&marker, {std::clamp(uv.x(), -kMaxCoordPx, kMaxCoordPx),
                                 std::clamp(uv.y(), -kMaxCoordPx, kMaxCoordPx)}});
  }
  LabelPlacer labels(image.size(), options.label_font_scale);
  for (const Visible& v : visible) {
    draw_marker_shape(image, fixed({v.uv.x, v.uv.y}), v.marker->radius_px, v.marker->colour, v.marker->filled);
    labels.block(v.uv, v.marker->radius_px);
  }
  for (const Visible& v : visible)
    if (!v.marker->label.empty()) labels.place(image, v.marker->label, v.uv, v.marker->radius_px, v.marker->colour);
}

}  // namespace evar::overlay::drawing
