#include <array>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>

#include "drawing.hpp"
#include "image_mat.hpp"

namespace evar::overlay {

namespace {

using namespace drawing;

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

using drawing::check_options;
using drawing::check_overlay;

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
