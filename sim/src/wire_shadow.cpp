#include "wire_shadow.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>

namespace evar::sim {
namespace {

constexpr int kSub = 4;  // subsamples per pixel side near a wire

// Per pixel near a wire: for each subsample the distance (mm, object space) to the nearest
// wire segment and that segment's 1/sin(angle to the ray).
struct WirePixel {
  std::array<float, kSub * kSub> d;
  std::array<float, kSub * kSub> obliquity;
};

}  // namespace

cv::Mat wire_transmittance(const geometry::ProjectionMatrix& P, const geometry::CArmView& view,
                           const std::vector<geometry::Polyline>& wires, double diameter_mm, double mu_per_mm,
                           std::vector<std::vector<Eigen::Vector2d>>* truth) {
  const int W = view.detector_cols, H = view.detector_rows;
  const geometry::PinholeCamera camera = geometry::pinhole_camera(P);
  const double scale3 = P.row(2).head<3>().norm();
  const double fu = P.row(0).head<3>().norm() / scale3, fv = P.row(1).head<3>().norm() / scale3;  // px per mm at unit depth
  const double R = 0.5 * diameter_mm;
  cv::Mat transmittance(H, W, CV_64F, cv::Scalar(1.0));
  for (const auto& wire : wires) {
    if (wire.size() < 2) continue;
    const auto dense = geometry::resample(wire, 0.25);
    std::vector<Eigen::Vector2d> px(dense.size());
    std::vector<double> depth(dense.size());
    std::vector<char> visible(dense.size());
    for (std::size_t k = 0; k < dense.size(); ++k) {
      const auto p = geometry::project(P, dense[k]);
      visible[k] = p.has_value();
      px[k] = p.value_or(Eigen::Vector2d::Zero());
      depth[k] = geometry::depth_mm(P, dense[k]);
    }
    std::vector<Eigen::Vector2d> curve;
    for (std::size_t k = 0; k < dense.size(); ++k)
      if (visible[k]) curve.push_back(px[k]);
    if (truth != nullptr) truth->push_back(std::move(curve));

    cv::Mat slot(H, W, CV_32S, cv::Scalar(-1));
    std::vector<WirePixel> pixels;
    for (std::size_t k = 0; k + 1 < dense.size(); ++k) {
      if (!visible[k] || !visible[k + 1]) continue;
      const Eigen::Vector2d a = px[k], b = px[k + 1];
      const double z = 0.5 * (depth[k] + depth[k + 1]);
      const Eigen::Vector3d dir3 = (dense[k + 1] - dense[k]).normalized();
      const Eigen::Vector3d ray = (0.5 * (dense[k] + dense[k + 1]) - camera.source_mm).normalized();
      const float obliquity = static_cast<float>(1.0 / std::max(ray.cross(dir3).norm(), 0.1));
      const double reach_px = R * std::max(fu, fv) / z + 1.5;
      const int u0 = std::max(0, static_cast<int>(std::floor(std::min(a.x(), b.x()) - reach_px)));
      const int u1 = std::min(W - 1, static_cast<int>(std::ceil(std::max(a.x(), b.x()) + reach_px)));
      const int v0 = std::max(0, static_cast<int>(std::floor(std::min(a.y(), b.y()) - reach_px)));
      const int v1 = std::min(H - 1, static_cast<int>(std::ceil(std::max(a.y(), b.y()) + reach_px)));
      const Eigen::Vector2d ab = b - a;
      const double len2 = std::max(ab.squaredNorm(), 1e-12);
      for (int v = v0; v <= v1; ++v)
        for (int u = u0; u <= u1; ++u) {
          int& s = slot.at<int>(v, u);
          if (s < 0) {
            s = static_cast<int>(pixels.size());
            WirePixel wp;
            wp.d.fill(1e9f);
            wp.obliquity.fill(1.0f);
            pixels.push_back(wp);
          }
          WirePixel& wp = pixels[static_cast<std::size_t>(s)];
          for (int i = 0; i < kSub * kSub; ++i) {
            const Eigen::Vector2d q(u - 0.5 + (i % kSub + 0.5) / kSub, v - 0.5 + (i / kSub + 0.5) / kSub);
            const double t = std::clamp((q - a).dot(ab) / len2, 0.0, 1.0);
            const Eigen::Vector2d off = q - (a + t * ab);
            const float d = static_cast<float>(std::hypot(off.x() * z / fu, off.y() * z / fv));
            if (d < wp.d[static_cast<std::size_t>(i)]) {
              wp.d[static_cast<std::size_t>(i)] = d;
              wp.obliquity[static_cast<std::size_t>(i)] = obliquity;
            }
          }
        }
    }
    for (int v = 0; v < H; ++v)
      for (int u = 0; u < W; ++u)
        if (const int s = slot.at<int>(v, u); s >= 0) {
          const WirePixel& wp = pixels[static_cast<std::size_t>(s)];
          double t = 0.0;
          for (int i = 0; i < kSub * kSub; ++i) {
            const double d = wp.d[static_cast<std::size_t>(i)];
            const double chord = d < R ? 2.0 * std::sqrt(R * R - d * d) * wp.obliquity[static_cast<std::size_t>(i)] : 0.0;
            t += std::exp(-mu_per_mm * chord);
          }
          transmittance.at<double>(v, u) *= t / (kSub * kSub);
        }
  }

  return transmittance;
}

}  // namespace evar::sim
