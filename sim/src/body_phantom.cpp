#include "evar/sim/body_phantom.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "evar/geometry/carm_projection.hpp"
#include "seeded_uniform.hpp"

namespace evar::sim {
namespace {

// Chord of the ray through the quadric Σ ((x_k - c_k)/a_k)² <= 1 over the first `dims` axes.
double quadric_chord(const double* centre, const double* semi, const double* origin, const double* dir, int dims) {
  double A = 0.0, B = 0.0, C = -1.0;
  for (int k = 0; k < dims; ++k) {
    const double o = (origin[k] - centre[k]) / semi[k], d = dir[k] / semi[k];
    A += d * d;
    B += 2.0 * o * d;
    C += o * o;
  }
  if (A <= 0.0) return 0.0;
  const double disc = B * B - 4.0 * A * C;
  if (disc <= 0.0) return 0.0;
  const double root = std::sqrt(disc);
  const double t0 = std::max((-B - root) / (2.0 * A), 0.0), t1 = (-B + root) / (2.0 * A);
  return std::max(t1 - t0, 0.0);
}

}  // namespace

double ellipsoid_chord(const Eigen::Vector3d& centre, const Eigen::Vector3d& semi_axes, const Eigen::Vector3d& origin,
                       const Eigen::Vector3d& direction) {
  return quadric_chord(centre.data(), semi_axes.data(), origin.data(), direction.data(), 3);
}

BodyPhantom default_body_phantom(unsigned seed) {
  BodyPhantom p;
  constexpr double kCancellous = 0.022, kCortical = 0.045;  // added to tissue, per mm
  // Lumbar vertebrae L5 (lowest) to L1, bodies centred 38 mm behind the bifurcation.
  for (int k = 0; k < 5; ++k) {
    const double z = 25.0 + 33.0 * k;
    const Eigen::Vector3d c(0.0, 38.0, z);
    p.parts.push_back({c, {24.0, 17.0, 12.5}, kCancellous});
    // Cortical shell: the outer ellipsoid minus a slightly smaller one.
    p.parts.push_back({c, {24.0, 17.0, 12.5}, kCortical - kCancellous});
    p.parts.push_back({c, {22.5, 15.5, 11.0}, -(kCortical - kCancellous)});
    for (const double side : {-1.0, 1.0}) {  // pedicles and posterior arch
      p.parts.push_back({{side * 16.0, 62.0, z + 3.0}, {5.5, 9.0, 7.0}, kCortical});
      p.parts.push_back({{side * 28.0, 70.0, z}, {9.0, 5.0, 5.0}, kCancellous});  // transverse process
    }
  }
  p.pelvis_begin = p.parts.size();
  p.parts.push_back({{0.0, 55.0, -40.0}, {45.0, 22.0, 45.0}, kCancellous});  // sacrum
  for (const double side : {-1.0, 1.0}) {
    // Iliac wing: a thin, wide plate (outer minus inner) with a dense rim.
    p.parts.push_back({{side * 95.0, 45.0, -50.0}, {62.0, 14.0, 50.0}, kCortical});
    p.parts.push_back({{side * 95.0, 45.0, -50.0}, {59.0, 10.0, 47.0}, -kCortical + 0.008});
    p.parts.push_back({{side * 90.0, 5.0, -150.0}, {24.0, 24.0, 24.0}, kCortical});  // femoral head
    p.parts.push_back({{side * 55.0, 10.0, -115.0}, {30.0, 15.0, 12.0}, kCancellous});  // pubic ramus
  }
  p.pelvis_end = p.parts.size();
  // Bowel gas: a few pockets in front of the spine, placed by the seed, all inside the body
  // (its front is at y = -90).
  SeededUniform uniform(seed);
  for (int k = 0; k < 4; ++k)
    p.parts.push_back({{uniform(-90.0, 90.0), uniform(-70.0, -30.0), uniform(-60.0, 150.0)},
                       {uniform(12.0, 35.0), uniform(8.0, 15.0), uniform(10.0, 25.0)},
                       -p.tissue_mu_per_mm});
  return p;
}

geometry::TriangleMesh pelvis_mesh(const BodyPhantom& phantom) {
  // A unit icosphere: the icosahedron, each face split in four three times, pushed out.
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> v{{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                                 {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  std::vector<Eigen::Vector3i> f{{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                                 {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  for (auto& x : v) x.normalize();
  for (int level = 0; level < 3; ++level) {
    std::map<std::pair<int, int>, int> midpoint;
    const auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto [it, added] = midpoint.try_emplace(key, static_cast<int>(v.size()));
      if (added) v.push_back((v[static_cast<std::size_t>(a)] + v[static_cast<std::size_t>(b)]).normalized());
      return it->second;
    };
    std::vector<Eigen::Vector3i> finer;
    for (const auto& t : f) {
      const int ab = mid(t[0], t[1]), bc = mid(t[1], t[2]), ca = mid(t[2], t[0]);
      finer.insert(finer.end(), {{t[0], ab, ca}, {t[1], bc, ab}, {t[2], ca, bc}, {ab, bc, ca}});
    }
    f = std::move(finer);
  }
  std::vector<const Ellipsoid*> bones;
  for (std::size_t k = phantom.pelvis_begin; k < phantom.pelvis_end && k < phantom.parts.size(); ++k)
    if (phantom.parts[k].mu_per_mm > 0.0) bones.push_back(&phantom.parts[k]);
  geometry::TriangleMesh mesh;
  mesh.V.resize(static_cast<Eigen::Index>(bones.size() * v.size()), 3);
  mesh.F.resize(static_cast<Eigen::Index>(bones.size() * f.size()), 3);
  for (std::size_t b = 0; b < bones.size(); ++b) {
    const auto base = static_cast<Eigen::Index>(b * v.size());
    for (std::size_t i = 0; i < v.size(); ++i)
      mesh.V.row(base + static_cast<Eigen::Index>(i)) = (bones[b]->centre_mm + v[i].cwiseProduct(bones[b]->semi_axes_mm)).transpose();
    for (std::size_t i = 0; i < f.size(); ++i)
      mesh.F.row(static_cast<Eigen::Index>(b * f.size() + i)) = (f[i].array() + static_cast<int>(base)).matrix().transpose();
  }
  return mesh;
}

void add_line_integrals(const BodyPhantom& phantom, const Eigen::Matrix4d& patient_to_world,
                        const Eigen::Matrix<double, 3, 4>& P, cv::Mat& A) {
  const int W = A.cols, H = A.rows;
  const geometry::PinholeCamera camera = geometry::pinhole_camera(P);
  const Eigen::Matrix3d R = patient_to_world.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = patient_to_world.topRightCorner<3, 1>();
  const Eigen::Vector3d o = R.transpose() * (camera.source_mm - t);  // source in patient coordinates
  // Ray directions in patient coordinates, once per pixel.
  std::vector<Eigen::Vector3d> dirs(static_cast<std::size_t>(W) * static_cast<std::size_t>(H));
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u)
      dirs[static_cast<std::size_t>(v) * W + u] = R.transpose() * geometry::back_projected_ray(camera, Eigen::Vector2d(u, v));
  const auto add = [&](int u0, int u1, int v0, int v1, auto&& chord) {
    for (int v = v0; v <= v1; ++v) {
      double* row = A.ptr<double>(v);
      for (int u = u0; u <= u1; ++u) row[u] += chord(dirs[static_cast<std::size_t>(v) * W + u]);
    }
  };
  add(0, W - 1, 0, H - 1, [&](const Eigen::Vector3d& d) {
    return phantom.tissue_mu_per_mm *
           quadric_chord(phantom.body_centre_mm.data(), phantom.body_semi_axes_mm.data(), o.data(), d.data(), 2);
  });
  for (const auto& e : phantom.parts) {
    // Pixel box of the part's bounding box; the whole detector if a corner is behind the source.
    double u0 = W, u1 = -1, v0 = H, v1 = -1;
    bool whole = false;
    for (int c = 0; c < 8; ++c) {
      const Eigen::Vector3d corner = e.centre_mm + Eigen::Vector3d((c & 1 ? 1 : -1) * e.semi_axes_mm.x(),
                                                                   (c & 2 ? 1 : -1) * e.semi_axes_mm.y(),
                                                                   (c & 4 ? 1 : -1) * e.semi_axes_mm.z());
      const auto px = geometry::project(P, R * corner + t);
      if (!px) {
        whole = true;
        break;
      }
      u0 = std::min(u0, px->x()), u1 = std::max(u1, px->x()), v0 = std::min(v0, px->y()), v1 = std::max(v1, px->y());
    }
    const int iu0 = whole ? 0 : std::max(0, static_cast<int>(std::floor(u0)) - 1);
    const int iu1 = whole ? W - 1 : std::min(W - 1, static_cast<int>(std::ceil(u1)) + 1);
    const int iv0 = whole ? 0 : std::max(0, static_cast<int>(std::floor(v0)) - 1);
    const int iv1 = whole ? H - 1 : std::min(H - 1, static_cast<int>(std::ceil(v1)) + 1);
    if (iu0 > iu1 || iv0 > iv1) continue;
    add(iu0, iu1, iv0, iv1, [&](const Eigen::Vector3d& d) { return e.mu_per_mm * ellipsoid_chord(e.centre_mm, e.semi_axes_mm, o, d); });
  }
}

}  // namespace evar::sim
