#include "evar/overlay/mesh_preview.hpp"

#include <algorithm>
#include <span>
#include <array>
#include <cassert>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>
#include <utility>
#include "evar/geometry/image_file.hpp"
#include "image_mat.hpp"

namespace evar::overlay {
namespace {

// Sub-pixel drawing: OpenCV takes fixed-point coordinates with this many fraction bits.
constexpr int kShift = 4;
constexpr double kFixedOne = 1 << kShift;
// Projected coordinates are clamped to this many pixels so fixed-point values stay far
// from int overflow; only a degenerate (near-source) projection gets anywhere near it.
constexpr double kMaxCoordPx = 1e5;
constexpr int kMaxPanelPx = 8192;

const Bgr kHalo{8, 8, 8};
const Bgr kText{235, 235, 235};
const Bgr kDimText{165, 160, 155};
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr int kTitleFont = cv::FONT_HERSHEY_DUPLEX;

cv::Scalar scalar(Bgr c) { return {static_cast<double>(c.b), static_cast<double>(c.g), static_cast<double>(c.r)}; }

// Image coordinates (px) -> OpenCV fixed-point drawing coordinates.
cv::Point fixed(const Eigen::Vector2d& uv) {
  const auto one = [](double x) {
    return static_cast<int>(std::lround(std::clamp(x, -kMaxCoordPx, kMaxCoordPx) * kFixedOne));
  };
  return {one(uv.x()), one(uv.y())};
}

std::string layer_name(std::size_t index, const std::string& legend) {
  return "layer " + std::to_string(index) + (legend.empty() ? "" : " ('" + legend + "')");
}

// Throws unless every face indexes an existing, finite vertex.
void check_mesh(const geometry::TriangleMesh& mesh, const std::string& where) {
  const auto nv = mesh.V.rows();
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int c = 0; c < 3; ++c) {
      const int i = mesh.F(f, c);
      if (i < 0 || i >= nv)
        throw std::invalid_argument(where + ": face " + std::to_string(f) + " references vertex " +
                                    std::to_string(i) + " of " + std::to_string(nv));
      if (!mesh.V.row(i).allFinite())
        throw std::invalid_argument(where + ": face " + std::to_string(f) + " references non-finite vertex " +
                                    std::to_string(i));
    }
}

void check_overlay(const Overlay& overlay) {
  for (std::size_t l = 0; l < overlay.layers.size(); ++l) {
    const MeshLayer& layer = overlay.layers[l];
    const std::string name = layer_name(l, layer.legend);
    if (!(layer.fill_alpha >= 0.0 && layer.fill_alpha <= 1.0))
      throw std::invalid_argument(name + ": fill_alpha must be in [0, 1]");
    if (layer.outline && layer.outline_px < 1) throw std::invalid_argument(name + ": outline_px must be >= 1");
    for (std::size_t m = 0; m < layer.meshes.size(); ++m)
      check_mesh(layer.meshes[m], name + " mesh " + std::to_string(m));
  }
  for (std::size_t p = 0; p < overlay.polylines.size(); ++p) {
    const PolylineLayer& line = overlay.polylines[p];
    if (line.thickness_px < 1)
      throw std::invalid_argument("polyline " + std::to_string(p) + ": thickness_px must be >= 1");
    for (const auto& point : line.points)
      if (!point.allFinite()) throw std::invalid_argument("polyline " + std::to_string(p) + " has a non-finite point");
  }
  for (std::size_t m = 0; m < overlay.markers.size(); ++m) {
    const Marker& marker = overlay.markers[m];
    if (!marker.position_lps.allFinite())
      throw std::invalid_argument("marker " + std::to_string(m) + " ('" + marker.label + "') is not finite");
    if (marker.radius_px < 1) throw std::invalid_argument("marker " + std::to_string(m) + ": radius_px must be >= 1");
  }
}

void check_options(const DrawOptions& options) {
  if (options.supersample < 1 || options.supersample > 8)
    throw std::invalid_argument("DrawOptions: supersample must be in 1 .. 8, got " +
                                std::to_string(options.supersample));
  if (!(options.label_font_scale > 0.0) || !std::isfinite(options.label_font_scale))
    throw std::invalid_argument("DrawOptions: label_font_scale must be positive");
}

// ---------------------------------------------------------------------------------------
// Mesh silhouettes

// A mask of samples covering part of the image's sample grid: the image pixels `pixels`,
// k x k samples each; sample (x, y) of the grid is mask(y - origin.y, x - origin.x) with
// origin = k · pixels.tl(), and the grid beyond the mask is empty.
struct SampleMask {
  cv::Rect pixels;
  cv::Point origin;  ///< in samples
  cv::Mat1b mask;
};

// Sets the samples (integer positions of the grid) inside triangle abc (sample coordinates),
// half-open like GPU rasterisers: rows a.y <= y < c.y, columns x_left <= x < x_right.
// Unlike cv::fillConvexPoly, which includes both ends of every span and so grows shapes
// by about half a sample (biasing area and, measured, position), this covers each sample
// by its centre: the filled area is unbiased and triangles sharing an edge leave no gap.
// Computed in grid coordinates whatever part the mask holds, so a sample is set or not
// independently of where the mask lies.
void fill_triangle(SampleMask& grid, std::array<Eigen::Vector2d, 3> t) {
  std::sort(t.begin(), t.end(), [](const Eigen::Vector2d& p, const Eigen::Vector2d& q) {
    return p.y() < q.y() || (p.y() == q.y() && p.x() < q.x());
  });
  const auto& [a, b, c] = t;
  // Always evaluated from the lower end point, so a shared edge gives identical x values.
  const auto x_at = [](const Eigen::Vector2d& p, const Eigen::Vector2d& q, double y) {
    return p.x() + (y - p.y()) * (q.x() - p.x()) / (q.y() - p.y());
  };
  const double left = grid.origin.x, right = grid.origin.x + grid.mask.cols;
  const int y0 = static_cast<int>(std::max<double>(grid.origin.y, std::ceil(a.y())));
  const int y1 = static_cast<int>(std::min<double>(grid.origin.y + grid.mask.rows, std::ceil(c.y())));
  for (int y = y0; y < y1; ++y) {
    const double xa = x_at(a, c, y), xb = y < b.y() ? x_at(a, b, y) : x_at(b, c, y);
    const int x0 = static_cast<int>(std::clamp(std::ceil(std::min(xa, xb)), left, right));
    const int x1 = static_cast<int>(std::clamp(std::ceil(std::max(xa, xb)), left, right));
    if (x1 > x0)
      std::memset(grid.mask.ptr<std::uint8_t>(y - grid.origin.y) + (x0 - grid.origin.x), 255,
                  static_cast<std::size_t>(x1 - x0));
  }
}

// The union of the layer's projected triangles, sampled `supersample` times finer than
// `size` along each axis (image pixel centre u = i maps to sample (u + 0.5) k - 0.5), held
// only over the whole image pixels that the triangles' bounding box touches, with one
// empty pixel around it where the image goes on (vessels cover a fraction of the frame;
// the fill, its coverage, the outline tracing and the blend then touch only that part).
SampleMask silhouette(const ViewProjection& view, const MeshLayer& layer, cv::Size size, int supersample) {
  const double near = view.near_depth();
  const double limit = kMaxCoordPx * supersample;
  struct Projected {
    std::vector<Eigen::Vector2d> points;
    std::vector<char> state;  // 1 projected, 2 cannot be projected, 0 not referenced
  };
  std::vector<Projected> meshes(layer.meshes.size());
  Eigen::AlignedBox2d box;
  for (std::size_t m = 0; m < layer.meshes.size(); ++m) {
    const auto& mesh = layer.meshes[m];
    auto& p = meshes[m];
    p.points.assign(static_cast<std::size_t>(mesh.V.rows()), Eigen::Vector2d::Zero());
    p.state.assign(static_cast<std::size_t>(mesh.V.rows()), 0);
    // Only referenced vertices are projected: erased faces may leave any vertex behind.
    for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
      for (int corner = 0; corner < 3; ++corner) {
        const auto i = static_cast<std::size_t>(mesh.F(f, corner));
        if (p.state[i] != 0) continue;
        const Eigen::Vector3d x = mesh.V.row(mesh.F(f, corner)).transpose();
        p.state[i] = view.depth(x) > near ? 1 : 2;
        if (p.state[i] != 1) continue;
        const Eigen::Vector2d uv = view.project(x);
        if (!uv.allFinite()) {  // a vertex near the double range projects to inf / inf
          p.state[i] = 2;
          continue;
        }
        p.points[i] = ((uv.array() + 0.5) * supersample - 0.5).cwiseMax(-limit).cwiseMin(limit);
        box.extend(p.points[i]);
      }
  }
  // Samples k·i .. k·i + k − 1 make up image pixel i.
  cv::Rect pixels;
  if (!box.isEmpty()) {
    const auto pixel = [&](double sample) { return static_cast<int>(std::floor(sample / supersample)); };
    const int x0 = std::max(0, pixel(box.min().x()) - 1), y0 = std::max(0, pixel(box.min().y()) - 1);
    const int x1 = std::min(size.width, pixel(box.max().x()) + 2), y1 = std::min(size.height, pixel(box.max().y()) + 2);
    if (x1 > x0 && y1 > y0) pixels = cv::Rect(x0, y0, x1 - x0, y1 - y0);
  }
  SampleMask grid{pixels, pixels.tl() * supersample,
                  cv::Mat1b::zeros(pixels.height * supersample, pixels.width * supersample)};
  if (pixels.empty()) return grid;
  for (std::size_t m = 0; m < layer.meshes.size(); ++m) {
    const auto& mesh = layer.meshes[m];
    const auto& p = meshes[m];
    for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
      const auto a = static_cast<std::size_t>(mesh.F(f, 0)), b = static_cast<std::size_t>(mesh.F(f, 1)),
                 c = static_cast<std::size_t>(mesh.F(f, 2));
      if (p.state[a] == 1 && p.state[b] == 1 && p.state[c] == 1) fill_triangle(grid, {p.points[a], p.points[b], p.points[c]});
    }
  }
  return grid;
}

// image = image * (1 - a) + colour * a with a = alpha * coverage / 255, per pixel.
void blend(cv::Mat& image, const cv::Mat1b& coverage, Bgr colour, double alpha) {
  if (alpha <= 0.0) return;
  const std::array<double, 3> c{static_cast<double>(colour.b), static_cast<double>(colour.g),
                                static_cast<double>(colour.r)};
  for (int y = 0; y < image.rows; ++y) {
    auto* px = image.ptr<cv::Vec3b>(y);
    const auto* cov = coverage.ptr<std::uint8_t>(y);
    for (int x = 0; x < image.cols; ++x) {
      if (cov[x] == 0) continue;
      const double a = alpha * cov[x] / 255.0;
      for (int k = 0; k < 3; ++k) px[x][k] = cv::saturate_cast<std::uint8_t>(px[x][k] * (1.0 - a) + c[k] * a);
    }
  }
}

// The mask's boundaries (outer and holes) as fixed-point polylines in image pixels.
std::vector<std::vector<cv::Point>> outline(const SampleMask& grid, int supersample) {
  std::vector<std::vector<cv::Point>> contours;
  if (!grid.mask.empty()) cv::findContours(grid.mask, contours, cv::RETR_LIST, cv::CHAIN_APPROX_NONE, grid.origin);
  std::vector<std::vector<cv::Point>> result;
  result.reserve(contours.size());
  std::vector<cv::Point> simplified;
  for (const auto& contour : contours) {
    // Straighten the fine raster's staircase; 0.6 fine px stays well under a pixel.
    cv::approxPolyDP(contour, simplified, 0.6, true);
    std::vector<cv::Point> out;
    out.reserve(simplified.size());
    for (const cv::Point& q : simplified) {
      const auto to_fixed = [&](int fine) {
        return static_cast<int>(std::lround(((fine + 0.5) / supersample - 0.5) * kFixedOne));
      };
      out.emplace_back(to_fixed(q.x), to_fixed(q.y));
    }
    result.push_back(std::move(out));
  }
  return result;
}

// ---------------------------------------------------------------------------------------
// Lines, markers, text

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

// Text with a dark halo; `origin` is the baseline start (OpenCV's putText convention).
void draw_text(cv::Mat& image, const std::string& text, cv::Point origin, int font, double scale, Bgr colour,
               int thickness = 1) {
  cv::putText(image, text, origin, font, scale, scalar(kHalo), thickness + 3, cv::LINE_AA);
  cv::putText(image, text, origin, font, scale, scalar(colour), thickness, cv::LINE_AA);
}

cv::Size text_size(const std::string& text, int font, double scale, int thickness, int* baseline = nullptr) {
  int base = 0;
  const cv::Size size = cv::getTextSize(text, font, scale, thickness, &base);
  if (baseline) *baseline = base;
  return size;
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

// Draws into every image (all of one size), rasterising the silhouettes and tracing their
// outlines once: the roadmap layer is drawn on black and on white to recover its colour and
// coverage, and the fine raster is most of the cost.
void draw_overlay(std::span<cv::Mat> images, const ViewProjection& view, const Overlay& overlay,
                  const DrawOptions& options) {
  if (images.empty()) return;
  const int k = options.supersample;
  const cv::Size size = images.front().size();
  std::vector<std::vector<std::vector<cv::Point>>> outlines(overlay.layers.size());
  for (std::size_t l = 0; l < overlay.layers.size(); ++l) {
    const MeshLayer& layer = overlay.layers[l];
    const SampleMask grid = silhouette(view, layer, size, k);
    if (layer.outline) outlines[l] = outline(grid, k);
    if (layer.fill_alpha <= 0.0 || grid.pixels.empty()) continue;
    cv::Mat1b coverage;
    if (k == 1)
      coverage = grid.mask;
    else
      cv::resize(grid.mask, coverage, grid.pixels.size(), 0.0, 0.0, cv::INTER_AREA);  // box average: exact coverage
    for (cv::Mat& image : images) {
      cv::Mat part = image(grid.pixels);
      blend(part, coverage, layer.colour, layer.fill_alpha);
    }
  }
  for (cv::Mat& image : images) draw_lines_and_markers(image, view, overlay, outlines, options);
}

void draw_overlay(cv::Mat& image, const ViewProjection& view, const Overlay& overlay, const DrawOptions& options) {
  draw_overlay(std::span<cv::Mat>(&image, 1), view, overlay, options);
}

// ---------------------------------------------------------------------------------------
// The comparison picture

constexpr std::array<StandardView, 2> kPanelViews{StandardView::AP, StandardView::Lateral};
constexpr int kTitleBandPx = 46;
constexpr int kSubtitleBandPx = 24;
constexpr double kLegendFontScale = 0.5;
constexpr int kLegendRowPx = 26;
constexpr int kLegendSwatchPx = 26;

Eigen::AlignedBox3d content_bounds(const Overlay& overlay) {
  Eigen::AlignedBox3d box;
  for (const MeshLayer& layer : overlay.layers)
    for (const auto& mesh : layer.meshes)
      for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
        for (int c = 0; c < 3; ++c) box.extend(mesh.V.row(mesh.F(f, c)).transpose().eval());
  for (const PolylineLayer& line : overlay.polylines)
    for (const auto& p : line.points) box.extend(p);
  for (const Marker& marker : overlay.markers) box.extend(marker.position_lps);
  return box;
}

// One legend entry per distinct (kind, text, style), in order of first appearance.
struct LegendEntry {
  enum class Kind { Mesh, Line, Marker } kind;
  std::string text;
  Bgr colour;
  double alpha = 0.0;  // mesh fill
  int thickness = 1;   // line
  bool filled = false;  // marker
};

std::vector<LegendEntry> legend_entries(const Overlay& overlay) {
  std::vector<LegendEntry> entries;
  const auto add = [&](LegendEntry e) {
    const bool seen = std::any_of(entries.begin(), entries.end(), [&](const LegendEntry& o) {
      return o.kind == e.kind && o.text == e.text && o.filled == e.filled;
    });
    if (!e.text.empty() && !seen) entries.push_back(std::move(e));
  };
  for (const MeshLayer& l : overlay.layers) add({LegendEntry::Kind::Mesh, l.legend, l.colour, l.fill_alpha, 1, false});
  for (const PolylineLayer& p : overlay.polylines)
    add({LegendEntry::Kind::Line, p.legend, p.colour, 0.0, p.thickness_px, false});
  for (const Marker& m : overlay.markers) add({LegendEntry::Kind::Marker, m.legend, m.colour, 0.0, 1, m.filled});
  return entries;
}

int legend_entry_width(const LegendEntry& entry) {
  return kLegendSwatchPx + 8 + text_size(entry.text, kFont, kLegendFontScale, 1).width + 28;
}

// Rows of entries that fit `width`, each row a list of entry indices.
std::vector<std::vector<std::size_t>> legend_rows(const std::vector<LegendEntry>& entries, int width) {
  std::vector<std::vector<std::size_t>> rows;
  int used = width;  // forces a first row
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const int w = legend_entry_width(entries[i]);
    if (used + w > width) {
      rows.emplace_back();
      used = 0;
    }
    rows.back().push_back(i);
    used += w;
  }
  return rows;
}

int header_height(const ComparisonPicture& picture) {
  return kTitleBandPx + (picture.subtitle.empty() ? 0 : kSubtitleBandPx);
}

int footer_height(const ComparisonPicture& picture, int width) {
  const auto rows = legend_rows(legend_entries(picture.overlay), width - 32);
  return rows.empty() ? 12 : 16 + static_cast<int>(rows.size()) * kLegendRowPx;
}

void draw_legend(cv::Mat& canvas, const ComparisonPicture& picture, int top) {
  const auto entries = legend_entries(picture.overlay);
  const auto rows = legend_rows(entries, canvas.cols - 32);
  int y = top + 8;
  for (const auto& row : rows) {
    int x = 16;
    const int mid = y + kLegendRowPx / 2;
    for (const std::size_t i : row) {
      const LegendEntry& e = entries[i];
      const cv::Rect swatch(x, mid - 7, kLegendSwatchPx, 14);
      switch (e.kind) {
        case LegendEntry::Kind::Mesh: {
          cv::Mat roi = canvas(swatch);
          blend(roi, cv::Mat1b(roi.size(), 255), e.colour, e.alpha);
          cv::rectangle(canvas, swatch, scalar(e.colour), 1, cv::LINE_AA);
          break;
        }
        case LegendEntry::Kind::Line:
          cv::line(canvas, {x, mid}, {x + kLegendSwatchPx, mid}, scalar(kHalo), e.thickness + 2, cv::LINE_AA);
          cv::line(canvas, {x, mid}, {x + kLegendSwatchPx, mid}, scalar(e.colour), e.thickness, cv::LINE_AA);
          break;
        case LegendEntry::Kind::Marker:
          draw_marker_shape(canvas, cv::Point((x + kLegendSwatchPx / 2) << kShift, mid << kShift), 5, e.colour,
                            e.filled);
          break;
      }
      const cv::Size ts = text_size(e.text, kFont, kLegendFontScale, 1);
      cv::putText(canvas, e.text, {x + kLegendSwatchPx + 8, mid + ts.height / 2}, kFont, kLegendFontScale,
                  scalar(kText), 1, cv::LINE_AA);
      x += legend_entry_width(e);
    }
    y += kLegendRowPx;
  }
}

// Patient direction letter for a unit LPS direction: the dominant axis, as on a viewer.
const char* direction_letter(const Eigen::Vector3d& d) {
  Eigen::Index axis = 0;
  d.cwiseAbs().maxCoeff(&axis);
  static constexpr std::array<std::array<const char*, 2>, 3> kLetters{{{"R", "L"}, {"A", "P"}, {"I", "S"}}};
  return kLetters[static_cast<std::size_t>(axis)][d[axis] > 0.0 ? 1 : 0];
}

// Panel caption: the view's name and, smaller, where the viewer stands.
std::pair<const char*, const char*> panel_caption(StandardView view) {
  switch (view) {
    case StandardView::AP: return {"AP", "frontal, patient's right on the left"};
    case StandardView::Lateral: return {"LATERAL", "viewed from the patient's left"};
  }
  return {"", ""};
}

// Scale bar in the panel's bottom-left corner: a round length of at most a quarter panel.
void draw_scale_bar(cv::Mat& panel, double mm_per_pixel, int margin) {
  static constexpr std::array<double, 10> kLengths{1, 2, 5, 10, 20, 50, 100, 200, 500, 1000};
  double length = kLengths.front();
  for (const double l : kLengths)
    if (l / mm_per_pixel <= 0.25 * panel.cols) length = l;
  const int px = static_cast<int>(std::lround(length / mm_per_pixel));
  const int x0 = 18, y = panel.rows - std::max(14, margin / 3);
  const cv::Scalar colour = scalar(kDimText);
  cv::line(panel, {x0, y}, {x0 + px, y}, colour, 1, cv::LINE_AA);
  cv::line(panel, {x0, y - 4}, {x0, y + 4}, colour, 1, cv::LINE_AA);
  cv::line(panel, {x0 + px, y - 4}, {x0 + px, y + 4}, colour, 1, cv::LINE_AA);
  char text[32];
  std::snprintf(text, sizeof text, "%g mm", length);
  cv::putText(panel, text, {x0 + px + 8, y + 5}, kFont, 0.45, colour, 1, cv::LINE_AA);
}

void draw_panel_frame(cv::Mat& panel, const PanelLayout& layout, double mm_per_pixel, int margin) {
  const auto [caption, detail] = panel_caption(layout.view);
  draw_text(panel, caption, {16, 28}, kFont, 0.6, kText, 1);
  draw_text(panel, detail, {16, 48}, kFont, 0.42, kDimText, 1);
  const ViewAxes& axes = layout.projection.axes();
  const double font = 0.6;
  const auto letter = [&](const Eigen::Vector3d& d, cv::Point centre) {
    const std::string s = direction_letter(d);
    const cv::Size ts = text_size(s, kFont, font, 1);
    draw_text(panel, s, {centre.x - ts.width / 2, centre.y + ts.height / 2}, kFont, font, kDimText);
  };
  letter(-axes.right, {14, panel.rows / 2});
  letter(axes.right, {panel.cols - 14, panel.rows / 2});
  letter(-axes.down, {panel.cols / 2, 20});
  letter(axes.down, {panel.cols / 2, panel.rows - 14});
  draw_scale_bar(panel, mm_per_pixel, margin);
}

cv::Mat render(const ComparisonPicture& picture, const PreviewOptions& options) {
  const ComparisonLayout layout = comparison_layout(picture, options);
  cv::Mat canvas(layout.height, layout.width, CV_8UC3, scalar(options.background));
  const int header = header_height(picture);

  // Title band.
  draw_text(canvas, picture.title, {16, 32}, kTitleFont, 0.75, kText, 1);
  if (!picture.subtitle.empty()) draw_text(canvas, picture.subtitle, {16, kTitleBandPx + 12}, kFont, 0.5, kDimText);
  char scale_text[64];
  std::snprintf(scale_text, sizeof scale_text, "%.3g mm/px, orthographic", layout.mm_per_pixel);
  const cv::Size st = text_size(scale_text, kFont, 0.45, 1);
  cv::putText(canvas, scale_text, {layout.width - st.width - 16, 30}, kFont, 0.45, scalar(kDimText), 1, cv::LINE_AA);

  for (const PanelLayout& panel_layout : layout.panels) {
    const cv::Rect rect(panel_layout.x, panel_layout.y, panel_layout.projection.width(),
                        panel_layout.projection.height());
    cv::Mat panel = canvas(rect);
    // Panels a shade lighter than the bands, so their extent (and scale) is visible.
    panel.setTo(scalar({static_cast<std::uint8_t>(std::min(255, options.background.b + 8)),
                        static_cast<std::uint8_t>(std::min(255, options.background.g + 8)),
                        static_cast<std::uint8_t>(std::min(255, options.background.r + 8))}));
    draw_overlay(panel, panel_layout.projection, picture.overlay, options.draw);
    draw_panel_frame(panel, panel_layout, layout.mm_per_pixel, options.margin_px);
  }
  // Gutter between the panels.
  if (layout.panels.size() == 2) {
    const int x = layout.panels[1].x;
    cv::line(canvas, {x, header}, {x, header + layout.panels[0].projection.height() - 1}, scalar(options.background),
             2);
  }
  draw_legend(canvas, picture, header + (layout.panels.empty() ? 0 : layout.panels[0].projection.height()));
  return canvas;
}

}  // namespace

// -----------------------------------------------------------------------------------------

Image Image::filled(int width, int height, Bgr colour) {
  if (width < 0 || height < 0) throw std::invalid_argument("Image::filled: negative size");
  Image image;
  image.width = width;
  image.height = height;
  image.bgr.resize(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 3);
  for (std::size_t i = 0; i < image.bgr.size(); i += 3) {
    image.bgr[i] = colour.b;
    image.bgr[i + 1] = colour.g;
    image.bgr[i + 2] = colour.r;
  }
  return image;
}

Bgr Image::at(int x, int y) const {
  assert(x >= 0 && x < width && y >= 0 && y < height);
  const auto i = (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)) * 3;
  return {bgr[i], bgr[i + 1], bgr[i + 2]};
}

void composite(Image& image, const ViewProjection& view, const Overlay& overlay, const DrawOptions& options) {
  check_options(options);
  check_overlay(overlay);
  cv::Mat mat = detail::wrap(image);  // shares image.bgr, so drawing lands in the caller's buffer
  if (mat.empty()) return;
  draw_overlay(mat, view, overlay, options);
}

void composite(std::span<Image* const> images, const ViewProjection& view, const Overlay& overlay,
               const DrawOptions& options) {
  check_options(options);
  check_overlay(overlay);
  std::vector<cv::Mat> mats;
  for (Image* image : images) {
    if (image->width != images.front()->width || image->height != images.front()->height)
      throw std::invalid_argument("composite: the images differ in size");
    mats.push_back(detail::wrap(*image));
  }
  if (mats.empty() || mats.front().empty()) return;
  draw_overlay(std::span<cv::Mat>(mats), view, overlay, options);
}

ComparisonLayout comparison_layout(const ComparisonPicture& picture, const PreviewOptions& options) {
  check_options(options.draw);
  check_overlay(picture.overlay);
  const int panel_w = options.width_px / 2;
  if (options.margin_px < 0 || panel_w <= 2 * options.margin_px)
    throw std::invalid_argument("comparison_layout: width_px " + std::to_string(options.width_px) +
                                " leaves no room for two panels with a " + std::to_string(options.margin_px) +
                                " px margin");
  if (options.mm_per_pixel < 0.0 || !std::isfinite(options.mm_per_pixel))
    throw std::invalid_argument("comparison_layout: mm_per_pixel must be 0 (fit) or positive");

  Eigen::AlignedBox3d bounds = options.bounds_lps.isEmpty() ? content_bounds(picture.overlay) : options.bounds_lps;
  if (bounds.isEmpty()) throw std::invalid_argument("comparison_layout: nothing to draw and no bounds given");
  // A flat or point-like scene still needs a finite, non-zero extent to fit.
  const Eigen::Vector3d centre = bounds.center();
  const Eigen::Vector3d half = (0.5 * bounds.sizes()).cwiseMax(0.5);
  bounds = Eigen::AlignedBox3d(centre - half, centre + half);

  ComparisonLayout layout;
  layout.bounds_lps = bounds;
  layout.mm_per_pixel = options.mm_per_pixel > 0.0
                            ? options.mm_per_pixel
                            : fit_mm_per_pixel(bounds, kPanelViews, panel_w, options.max_panel_height_px,
                                               options.margin_px);
  double content_v = 0.0;
  for (const StandardView view : kPanelViews) content_v = std::max(content_v, view_extent_mm(view, bounds).y());
  const double panel_h_exact = content_v / layout.mm_per_pixel + 2.0 * options.margin_px;
  if (!(panel_h_exact <= kMaxPanelPx))
    throw std::invalid_argument("comparison_layout: panel would be " + std::to_string(panel_h_exact) +
                                " px tall at " + std::to_string(layout.mm_per_pixel) + " mm/px (limit " +
                                std::to_string(kMaxPanelPx) + ")");
  const int panel_h = static_cast<int>(std::ceil(panel_h_exact - 1e-9));
  const int header = header_height(picture);
  layout.width = 2 * panel_w;
  layout.height = header + panel_h + footer_height(picture, layout.width);
  for (std::size_t i = 0; i < kPanelViews.size(); ++i) {
    const StandardView view = kPanelViews[i];
    layout.panels.push_back({view, static_cast<int>(i) * panel_w, header,
                             OrthographicProjection::fit(view, bounds, layout.mm_per_pixel, panel_w, panel_h)});
  }
  return layout;
}

Image render_comparison(const ComparisonPicture& picture, const PreviewOptions& options) {
  const cv::Mat canvas = render(picture, options);
  Image image;
  image.width = canvas.cols;
  image.height = canvas.rows;
  assert(canvas.isContinuous());
  image.bgr.assign(canvas.data, canvas.data + canvas.total() * canvas.elemSize());
  return image;
}

void write_png(const std::filesystem::path& path, const Image& image) {
  // PNG whatever the extension; a failure names the file and its reason, and leaves no
  // truncated picture behind.
  geometry::write_image_file(path, detail::wrap(image), {.format = ".png"});
}

void write_comparison_png(const std::filesystem::path& path, const ComparisonPicture& picture,
                          const PreviewOptions& options) {
  write_png(path, render_comparison(picture, options));
}

ComparisonPicture deformation_comparison(std::string title, std::vector<geometry::TriangleMesh> before,
                                         std::vector<geometry::TriangleMesh> after, geometry::Polyline device,
                                         const std::vector<geometry::ControlPoint>& landmarks_before,
                                         const std::vector<geometry::ControlPoint>& landmarks_after) {
  if (landmarks_before.size() != landmarks_after.size())
    throw std::invalid_argument("deformation_comparison: " + std::to_string(landmarks_before.size()) +
                                " landmarks before but " + std::to_string(landmarks_after.size()) + " after");
  const Bgr grey{200, 200, 200}, deformed{50, 100, 255}, wire{80, 255, 120}, landmark{255, 210, 80};
  ComparisonPicture picture;
  picture.title = std::move(title);
  Overlay& o = picture.overlay;
  o.layers.push_back({"preoperative (undeformed)", std::move(before), grey, 0.16, true, 1});
  o.layers.push_back({"deformed", std::move(after), deformed, 0.38, true, 2});
  o.polylines.push_back({"device", std::move(device), wire, 2});
  for (std::size_t i = 0; i < landmarks_before.size(); ++i)
    o.polylines.push_back({"", {landmarks_before[i].position_lps, landmarks_after[i].position_lps}, landmark, 1});
  // Only the moved landmark is labelled: two labels a few mm apart would collide.
  for (const auto& p : landmarks_before)
    o.markers.push_back({p.position_lps, "", "landmark before", landmark, false, 5});
  for (const auto& p : landmarks_after)
    o.markers.push_back({p.position_lps, p.label, "landmark after", landmark, true, 4});
  return picture;
}

}  // namespace evar::overlay
