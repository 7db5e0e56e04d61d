#include "evar/sim/xray_render.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "wire_shadow.hpp"

namespace evar::sim {

namespace {

// Ray crossings of the contrast meshes per pixel: the distance from the source, signed +
// where the ray leaves a mesh and − where it enters. A handful per pixel; beyond kMax
// (vessels seen end-on through many folds) the pixel falls back to Σ exits − Σ entries,
// which is exact for disjoint meshes.
struct Crossings {
  static constexpr int kMax = 16;
  int W = 0;
  std::vector<std::array<float, kMax>> t;
  std::vector<std::uint8_t> n;
  std::vector<float> sum;  // Σ signed t, for the fallback
  std::vector<char> overflow;
  Crossings(int w, int h)
      : W(w), t(static_cast<std::size_t>(w) * static_cast<std::size_t>(h)), n(t.size(), 0), sum(t.size(), 0.0f),
        overflow(t.size(), 0) {}
  void add(int u, int v, float signed_t) {
    const std::size_t i = static_cast<std::size_t>(v) * static_cast<std::size_t>(W) + static_cast<std::size_t>(u);
    sum[i] += signed_t;
    if (n[i] < kMax) t[i][n[i]++] = signed_t;
    else overflow[i] = 1;
  }
  // Length of the union of the meshes' insides along the ray.
  double union_length(std::size_t i) const {
    if (overflow[i]) return std::max(0.0, static_cast<double>(sum[i]));
    std::array<float, kMax> e = t[i];
    const int m = n[i];
    for (int k = 1; k < m; ++k)  // insertion sort by distance: a handful of entries
      for (int j = k; j > 0 && std::abs(e[static_cast<std::size_t>(j)]) < std::abs(e[static_cast<std::size_t>(j - 1)]); --j)
        std::swap(e[static_cast<std::size_t>(j)], e[static_cast<std::size_t>(j - 1)]);
    int depth = 0;
    double length = 0.0, start = 0.0;
    for (int k = 0; k < m; ++k) {
      const double at = std::abs(e[static_cast<std::size_t>(k)]);
      if (e[static_cast<std::size_t>(k)] < 0.0f) {
        if (depth++ == 0) start = at;
      } else if (depth > 0 && --depth == 0) {
        length += at - start;
      }
    }
    // Unbalanced (a crossing lost at a grazing edge): the signed sum instead.
    return depth == 0 ? length : std::max(0.0, static_cast<double>(sum[i]));
  }
};

}  // namespace

void add_path_lengths(const std::vector<const geometry::TriangleMesh*>& meshes, const Eigen::Matrix4d& patient_to_world,
                      const geometry::ProjectionMatrix& P, cv::Mat& L) {
  const int W = L.cols, H = L.rows;
  const geometry::PinholeCamera camera = geometry::pinhole_camera(P);
  const Eigen::Matrix3d R = patient_to_world.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = patient_to_world.topRightCorner<3, 1>();
  Crossings crossings(W, H);
  for (const auto* mesh : meshes) {
    std::vector<Eigen::Vector3d> X(static_cast<std::size_t>(mesh->V.rows()));
    std::vector<Eigen::Vector2d> x(X.size());
    std::vector<char> ok(X.size());
    for (std::size_t i = 0; i < X.size(); ++i) {
      X[i] = R * mesh->V.row(static_cast<Eigen::Index>(i)).transpose() + t;
      const auto p = geometry::project(P, X[i]);
      ok[i] = p.has_value();
      x[i] = p.value_or(Eigen::Vector2d::Zero());
    }
    for (Eigen::Index f = 0; f < mesh->F.rows(); ++f) {
      const auto a = static_cast<std::size_t>(mesh->F(f, 0)), b = static_cast<std::size_t>(mesh->F(f, 1)),
                 c = static_cast<std::size_t>(mesh->F(f, 2));
      if (!ok[a] || !ok[b] || !ok[c]) continue;
      const Eigen::Vector3d n = (X[b] - X[a]).cross(X[c] - X[a]);
      const double facing = n.dot(X[a] - camera.source_mm);  // > 0: the ray leaves through it
      if (facing == 0.0) continue;
      const double sign = facing > 0.0 ? 1.0 : -1.0;
      // Edge functions in pixel space, oriented counter-clockwise.
      Eigen::Vector2d p0 = x[a], p1 = x[b], p2 = x[c];
      double area = (p1 - p0).x() * (p2 - p0).y() - (p1 - p0).y() * (p2 - p0).x();
      if (area == 0.0) continue;
      if (area < 0.0) std::swap(p1, p2), area = -area;
      const int u0 = std::max(0, static_cast<int>(std::ceil(std::min({p0.x(), p1.x(), p2.x()}))));
      const int u1 = std::min(W - 1, static_cast<int>(std::floor(std::max({p0.x(), p1.x(), p2.x()}))));
      const int v0 = std::max(0, static_cast<int>(std::ceil(std::min({p0.y(), p1.y(), p2.y()}))));
      const int v1 = std::min(H - 1, static_cast<int>(std::floor(std::max({p0.y(), p1.y(), p2.y()}))));
      const Eigen::Vector2d e[3][2] = {{p1, p2}, {p2, p0}, {p0, p1}};
      // Top-left rule: a pixel centre exactly on an edge belongs to the triangle only for
      // top or left edges, so neighbours sharing the edge count it once. Each edge function
      // is evaluated from the edge's lexicographically smaller end, so the two triangles
      // sharing an edge get exactly opposite values, not two roundings of them.
      bool top_left[3], flipped[3];
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector2d d = e[k][1] - e[k][0];
        top_left[k] = (d.y() == 0.0 && d.x() < 0.0) || d.y() > 0.0;
        flipped[k] = std::make_pair(e[k][1].x(), e[k][1].y()) < std::make_pair(e[k][0].x(), e[k][0].y());
      }
      const double plane_d = n.dot(X[a]);
      for (int v = v0; v <= v1; ++v)
        for (int u = u0; u <= u1; ++u) {
          const Eigen::Vector2d q(u, v);
          bool inside = true;
          for (int k = 0; k < 3 && inside; ++k) {
            const Eigen::Vector2d& from = flipped[k] ? e[k][1] : e[k][0];
            const Eigen::Vector2d& to = flipped[k] ? e[k][0] : e[k][1];
            const Eigen::Vector2d d = to - from, r = q - from;
            const double w = flipped[k] ? -(d.x() * r.y() - d.y() * r.x()) : d.x() * r.y() - d.y() * r.x();
            inside = w > 0.0 || (w == 0.0 && top_left[k]);
          }
          if (!inside) continue;
          const Eigen::Vector3d ray = geometry::back_projected_ray(camera, q);
          const double denom = n.dot(ray);
          if (denom == 0.0) continue;
          crossings.add(u, v, static_cast<float>(sign * (plane_d - n.dot(camera.source_mm)) / denom));
        }
    }
  }
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) L.at<double>(v, u) += crossings.union_length(static_cast<std::size_t>(v) * W + u);
}

XRayExpected expected_xray(const geometry::CArmView& view, const XRayContent& content, const XRayOptions& o) {
  const int W = view.detector_cols, H = view.detector_rows;
  if (W <= 0 || H <= 0) throw std::invalid_argument("expected_xray: empty detector");
  if (!(o.photons_per_pixel > 0.0) || !(o.wire_diameter_mm > 0.0) || !(o.iodine_mu_per_mm >= 0.0))
    throw std::invalid_argument("expected_xray: photons > 0, a positive wire diameter and iodine attenuation >= 0 are required");
  const geometry::ProjectionMatrix P = geometry::projection_matrix(view);
  cv::Mat A(H, W, CV_64F, cv::Scalar(0.0));
  if (content.body != nullptr) {
    add_line_integrals(*content.body, content.patient_to_world, P, A);
    // Automatic exposure control: the dose is set so that the least attenuated ray of the
    // field (through the body, before contrast and devices) gets photons_per_pixel.
    double a_min = 0.0;
    cv::minMaxLoc(A, &a_min);
    A -= a_min;
  }
  if (content.contrast_fraction > 0.0 && !content.contrast.empty()) {
    cv::Mat L(H, W, CV_64F, cv::Scalar(0.0));
    add_path_lengths(content.contrast, content.patient_to_world, P, L);
    A += (content.contrast_fraction * o.iodine_mu_per_mm) * cv::max(L, 0.0);
  }
  XRayExpected out;
  std::vector<geometry::Polyline> wires;
  const Eigen::Matrix3d R = content.patient_to_world.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = content.patient_to_world.topRightCorner<3, 1>();
  for (const auto& w : content.wires) {
    geometry::Polyline world;
    for (const auto& p : w) world.push_back(R * p + t);
    wires.push_back(std::move(world));
  }
  const cv::Mat T = wire_transmittance(P, view, wires, o.wire_diameter_mm, o.wire_mu_per_mm, &out.wire_truth);
  cv::exp(-A, out.quanta);
  out.quanta = o.photons_per_pixel * out.quanta.mul(T);
  return out;
}

cv::Mat detect(const cv::Mat& expected, const XRayOptions& o, std::uint64_t seed) {
  if (expected.type() != CV_64F) throw std::invalid_argument("detect: expected quanta must be CV_64F");
  if (o.bits < 8 || o.bits > 16) throw std::invalid_argument("detect: 8 to 16 bits");
  if (!(o.photons_per_pixel > 0.0) || !(o.electronic_noise >= 0.0) || !(o.detector_blur_px >= 0.0))
    throw std::invalid_argument("detect: photons > 0, noise >= 0 and blur >= 0 are required");
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  cv::Mat n(expected.size(), CV_32F);
  for (int v = 0; v < expected.rows; ++v) {
    const double* e = expected.ptr<double>(v);
    float* out = n.ptr<float>(v);
    for (int u = 0; u < expected.cols; ++u) {
      const double mean = e[u];
      if (mean > 50.0) {
        out[u] = static_cast<float>(mean + std::sqrt(mean) * gauss(rng));
      } else if (mean > 0.0) {
        std::poisson_distribution<long> poisson(mean);
        out[u] = static_cast<float>(poisson(rng));
      } else {
        out[u] = 0.0f;  // no quanta expected (Poisson needs a positive mean)
      }
    }
  }
  if (o.detector_blur_px > 0.0) cv::GaussianBlur(n, n, cv::Size(0, 0), o.detector_blur_px, o.detector_blur_px, cv::BORDER_REFLECT);
  const double full_scale = (1 << o.bits) - 1;
  const double gain = 0.9 * full_scale / o.photons_per_pixel;
  cv::Mat image(expected.size(), CV_16UC1);
  for (int v = 0; v < expected.rows; ++v) {
    const float* q = n.ptr<float>(v);
    std::uint16_t* out = image.ptr<std::uint16_t>(v);
    for (int u = 0; u < expected.cols; ++u)
      out[u] = static_cast<std::uint16_t>(std::clamp(std::round(gain * (q[u] + o.electronic_noise * gauss(rng))), 0.0, full_scale));
  }
  return image;
}

}  // namespace evar::sim
