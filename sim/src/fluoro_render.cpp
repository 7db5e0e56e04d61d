#include "evar/sim/fluoro_render.hpp"

#include "wire_shadow.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <stdexcept>

namespace evar::sim {

namespace {

double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

// Inside-ness of an ellipse with a soft rim of `soft` mm, 1 inside, 0 outside.
double ellipse(double x, double y, double cx, double cy, double rx, double ry, double soft) {
  const double r = std::hypot((x - cx) / rx, (y - cy) / ry);
  const double mean_radius = 0.5 * (rx + ry);
  return 1.0 - smoothstep(1.0 - soft / mean_radius, 1.0 + soft / mean_radius, r);
}

// Line integrals (dimensionless μ·L) of a schematic abdomen and pelvis, in object-plane mm
// at the isocenter (x to the image right, y down).
double anatomy_at(double x, double y) {
  double a = 2.2 * (1.0 - std::pow(std::min(std::abs(x) / 260.0, 1.0), 2.0));  // soft tissue slab
  a += 0.15 * std::sin(x / 70.0) * std::cos(y / 55.0);                            // bowel gas, fat
  a -= 0.35 * ellipse(x, y, -60.0, -80.0, 35.0, 22.0, 8.0);                          // a gas bubble
  // Spine: vertebral bodies every 32 mm (26 mm tall, 48 mm wide, bone adds 0.8), their
  // cortical walls and endplates a little denser at the silhouette (0.25 over 1.5 mm),
  // oval pedicles (0.3) beside them.
  if (std::abs(x) < 40.0) {
    const double cy = 32.0 * std::round(y / 32.0);
    const double body = ellipse(x, y, 0.0, cy, 24.0, 13.0, 2.0);
    const double inner = ellipse(x, y, 0.0, cy, 22.5, 11.5, 1.0);
    a += 0.8 * body + 0.25 * std::max(body - inner, 0.0);
    for (const double side : {-1.0, 1.0}) {
      const double ped = ellipse(x, y, side * 16.0, cy - 5.0, 5.0, 6.5, 1.0);
      const double ped_in = ellipse(x, y, side * 16.0, cy - 5.0, 3.5, 5.0, 1.0);
      a += 0.3 * std::max(ped - ped_in, 0.0) + 0.1 * ped_in;
    }
  }
  // Pelvis: iliac wings (denser rims), femoral heads.
  for (const double side : {-1.0, 1.0}) {
    const double wing = ellipse(x, y, side * 95.0, 190.0, 85.0, 65.0, 3.0);
    const double hole = ellipse(x, y, side * 95.0, 190.0, 78.0, 58.0, 3.0);
    a += 0.5 * wing + 0.4 * std::max(wing - hole, 0.0);
    a += 1.4 * ellipse(x, y, side * 85.0, 300.0, 24.0, 24.0, 2.0);
  }
  return std::max(a, 0.0);
}

}  // namespace

geometry::Polyline iliac_guidewire(double shift_x_mm) {
  geometry::Polyline w;
  for (int k = 60; k >= 0; --k) {
    const double s = k / 60.0;
    w.emplace_back(shift_x_mm - 40.0 + 45.0 * s + 8.0 * std::sin(3.0 * s), 12.0 * std::sin(2.0 * s) - 5.0,
                   -150.0 + 200.0 * s);
  }
  return w;
}

FluoroFrame render_fluoro(const geometry::ProjectionMatrix& P, const geometry::CArmView& view,
                          const std::vector<geometry::Polyline>& wires, const FluoroOptions& o) {
  const int W = view.detector_cols, H = view.detector_rows;
  if (W <= 0 || H <= 0) throw std::invalid_argument("render_fluoro: empty detector");
  if (!(o.photons_per_pixel > 0.0) || o.bits < 8 || o.bits > 16 || !(o.wire_diameter_mm > 0.0))
    throw std::invalid_argument("render_fluoro: photons > 0, 8 to 16 bits and a positive wire diameter are required");
  const double scale3 = P.row(2).head<3>().norm();
  const double fu = P.row(0).head<3>().norm() / scale3, fv = P.row(1).head<3>().norm() / scale3;  // px per mm at unit depth

  FluoroFrame out;
  // Anatomy in object-plane mm at the isocenter's depth.
  const double z_iso = std::max(geometry::depth_mm(P, Eigen::Vector3d::Zero()), 1.0);
  const Eigen::Vector2d centre = geometry::project(P, Eigen::Vector3d::Zero()).value_or(Eigen::Vector2d(W / 2.0, H / 2.0));
  cv::Mat A(H, W, CV_64F, cv::Scalar(0.0));
  if (o.anatomy)
    for (int v = 0; v < H; ++v)
      for (int u = 0; u < W; ++u)
        A.at<double>(v, u) = o.anatomy_scale * anatomy_at((u - centre.x()) * z_iso / fu, (v - centre.y()) * z_iso / fv);
  if (o.collimation_px > 0)
    for (int v = 0; v < H; ++v)
      for (int u = 0; u < W; ++u)
        if (u < o.collimation_px || v < o.collimation_px || u >= W - o.collimation_px || v >= H - o.collimation_px)
          A.at<double>(v, u) += 6.0;  // lead shutters

  // Wires.
  const cv::Mat transmittance = wire_transmittance(P, view, wires, o.wire_diameter_mm, o.wire_mu_per_mm, &out.truth);

  // Quanta, noise, detector.
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double full_scale = (1 << o.bits) - 1;
  const double gain = 0.9 * full_scale / o.photons_per_pixel;
  out.image = cv::Mat(H, W, CV_16UC1);
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      const double mean = o.photons_per_pixel * std::exp(-A.at<double>(v, u)) * transmittance.at<double>(v, u);
      double n;
      if (mean > 50.0) {
        n = mean + std::sqrt(mean) * gauss(rng);
      } else {
        std::poisson_distribution<long> poisson(mean);
        n = static_cast<double>(poisson(rng));
      }
      n += o.electronic_noise * gauss(rng);
      out.image.at<std::uint16_t>(v, u) = static_cast<std::uint16_t>(std::clamp(std::round(gain * n), 0.0, full_scale));
    }
  return out;
}

}  // namespace evar::sim
