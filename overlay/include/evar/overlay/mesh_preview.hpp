#pragma once
// Roadmap drawing: vessel meshes as interventionalists know a roadmap (the union of the
// projected triangles filled translucently, with a crisp antialiased outline), devices as
// antialiased lines and landmarks as labelled rings, composited into an image through a
// ViewProjection. On top of it, the two-panel comparison picture (AP + lateral) of a
// deformation that `evarnode deform` writes as DIR/preview.png.
//
// OpenCV is a private dependency: images cross this header as packed BGR bytes.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "evar/base/atomic_file.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/triangle_mesh.hpp"
#include "evar/overlay/view_projection.hpp"

namespace evar::overlay {

/// An 8-bit colour in OpenCV's channel order (blue, green, red).
struct Bgr {
  std::uint8_t b = 0, g = 0, r = 0;
  friend bool operator==(const Bgr&, const Bgr&) = default;
};

/// A packed 8-bit BGR image: row-major, 3 bytes per pixel, no row padding.
struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> bgr;  ///< width * height * 3 bytes

  /// A width x height image (px, >= 0) of one colour.
  static Image filled(int width, int height, Bgr colour);
  /// Colour of pixel (x, y); no bounds check beyond an assert.
  Bgr at(int x, int y) const;
};

/// Meshes drawn as one roadmap silhouette: the union of all their projected triangles,
/// alpha-blended in `colour`, outlined along the union's boundary (holes included), so a
/// vessel tree shows no seams where its tubes overlap.
struct MeshLayer {
  std::string legend;                          ///< legend text; empty = not in the legend
  std::vector<geometry::TriangleMesh> meshes;  ///< LPS mm; only vertices referenced by a
                                               ///< face are used (erased faces may leave
                                               ///< vertices unreferenced)
  Bgr colour;
  double fill_alpha = 0.3;  ///< opacity of the fill in [0, 1]; 0 = outline only
  bool outline = true;
  int outline_px = 1;       ///< outline thickness (px, >= 1)
};

/// An open polyline (the device), drawn antialiased over a dark halo so it stays visible
/// on any background.
struct PolylineLayer {
  std::string legend;           ///< legend text; empty = not in the legend
  geometry::Polyline points;    ///< #P LPS mm; fewer than 2 points draws nothing
  Bgr colour;
  int thickness_px = 2;         ///< line width (px, >= 1)
};

/// A landmark: a ring (hollow) or a disc (filled) with an optional text label beside it.
struct Marker {
  Eigen::Vector3d position_lps = Eigen::Vector3d::Zero();  ///< mm
  std::string label;    ///< drawn beside the marker, away from the view centre; empty = none
  std::string legend;   ///< legend text; markers with the same legend share one entry
  Bgr colour;
  bool filled = false;
  int radius_px = 5;    ///< (px, >= 1)
};

/// Everything drawn into one view, bottom to top: all mesh fills (in order), all mesh
/// outlines (so an earlier layer's outline shows through a later layer's fill),
/// polylines, markers, labels.
struct Overlay {
  std::vector<MeshLayer> layers;
  std::vector<PolylineLayer> polylines;
  std::vector<Marker> markers;
};

struct DrawOptions {
  /// Silhouette masks are rasterised at this many samples per pixel along each axis and
  /// averaged down, which antialiases the fill and puts the outline within 1/supersample
  /// px of the true boundary. 1 .. 8; 4 for still pictures, 1 or 2 for live video.
  int supersample = 4;
  double label_font_scale = 0.45;  ///< Hershey simplex; 0.45 is about 9 px cap height
};

/// Draws `overlay` into `image` as seen through `view`, whose pixel frame is the image's
/// (view pixel (u, v) lands on image pixel (u, v); the view's own width/height are not
/// used, anything outside the image is clipped). Triangles, segments and markers with a
/// point at depth <= view.near_depth() are skipped.
/// Throws std::invalid_argument for an image whose byte count is not width*height*3,
/// bad options or layer parameters, a face index out of range or a referenced vertex that
/// is not finite (naming the layer and face).
void composite(Image& image, const ViewProjection& view, const Overlay& overlay, const DrawOptions& options = {});
/// The same drawing into each of `images` (all of one size; std::invalid_argument if not),
/// the silhouettes rasterised and outlined once: each image ends as composite() leaves it.
void composite(std::span<Image* const> images, const ViewProjection& view, const Overlay& overlay,
               const DrawOptions& options = {});

/// The comparison picture: the same overlay in an AP and a lateral panel side by side at
/// one shared scale, a title, a legend and a scale bar.
struct ComparisonPicture {
  std::string title;
  std::string subtitle;  ///< one smaller line under the title (e.g. what was measured); may be empty
  Overlay overlay;
};

struct PreviewOptions {
  int width_px = 1400;             ///< whole picture; each panel gets half (rounded down)
  int max_panel_height_px = 1000;  ///< the scale grows (coarser) if the content would be taller
  int margin_px = 56;              ///< free space around the content inside each panel
  double mm_per_pixel = 0.0;       ///< > 0: use this scale (panel height follows); 0 = fit
  Eigen::AlignedBox3d bounds_lps;  ///< mm; empty (the default) = bounds of everything drawn
  Bgr background{26, 22, 20};      ///< near-black, like a reading room monitor
  DrawOptions draw;
};

/// Where each panel sits in the picture and how it projects: lets tests (and callers that
/// annotate the picture) map patient points to picture pixels.
struct PanelLayout {
  StandardView view;
  int x = 0, y = 0;                   ///< top-left corner in the picture (px)
  OrthographicProjection projection;  ///< panel pixel frame; its width/height are the panel's
};

struct ComparisonLayout {
  int width = 0, height = 0;       ///< whole picture (px)
  double mm_per_pixel = 0.0;       ///< shared by both panels
  Eigen::AlignedBox3d bounds_lps;  ///< mm, what was fitted (each extent widened to >= 1 mm)
  std::vector<PanelLayout> panels;  ///< AP, then lateral
};

/// The layout render_comparison uses. Throws std::invalid_argument when there is nothing
/// to draw and no bounds are given, for options that leave no room (width below 2 panels
/// of twice the margin, a panel taller than 8192 px at a fixed scale), or for a face index
/// out of range / non-finite referenced vertex.
ComparisonLayout comparison_layout(const ComparisonPicture& picture, const PreviewOptions& options = {});

/// Renders the picture (exceptions as comparison_layout and composite).
Image render_comparison(const ComparisonPicture& picture, const PreviewOptions& options = {});

/// Writes an image as a PNG file at `path` (whatever its extension). Throws
/// std::runtime_error naming the path (and the system's reason) when it cannot be written.
void write_png(const std::filesystem::path& path, const Image& image,
               base::Durability durability = base::Durability::Synced);

/// Renders the picture and writes it as a PNG file at `path` (whatever its extension).
/// Throws std::runtime_error naming the path (and the system's reason) when the file
/// cannot be written.
void write_comparison_png(const std::filesystem::path& path, const ComparisonPicture& picture,
                          const PreviewOptions& options = {});

/// The standard deformation comparison: the undeformed meshes in light grey, the deformed
/// meshes in orange-red, the device in bright green, landmarks before as hollow rings and
/// after as labelled discs (paired by index; labels from `landmarks_after`), each with a
/// thin line showing how it moved. `before`/`after` are the vessels' meshes (LPS mm; the
/// deformed ones may have erased faces), `device` the guidewire (LPS mm).
ComparisonPicture deformation_comparison(std::string title, std::vector<geometry::TriangleMesh> before,
                                         std::vector<geometry::TriangleMesh> after, geometry::Polyline device,
                                         const std::vector<geometry::ControlPoint>& landmarks_before,
                                         const std::vector<geometry::ControlPoint>& landmarks_after);

}  // namespace evar::overlay
