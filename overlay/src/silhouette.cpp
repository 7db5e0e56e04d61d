#include <array>

#include "drawing.hpp"

namespace evar::overlay::drawing {

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

}  // namespace evar::overlay::drawing
