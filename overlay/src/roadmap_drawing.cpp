#include <cassert>
#include <stdexcept>
#include <string>

#include "drawing.hpp"
#include "evar/geometry/image_file.hpp"
#include "image_mat.hpp"

namespace evar::overlay {

namespace drawing {

namespace {

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

}  // namespace

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

}  // namespace drawing

using drawing::check_options;
using drawing::check_overlay;
using drawing::draw_overlay;

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

void write_png(const std::filesystem::path& path, const Image& image, base::Durability durability) {
  // PNG whatever the extension; a failure names the file and its reason, and leaves no
  // truncated picture behind.
  geometry::write_image_file(path, detail::wrap(image), {.format = ".png", .params = {}, .durability = durability});
}

}  // namespace evar::overlay
