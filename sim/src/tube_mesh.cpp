#include "evar/sim/tube_mesh.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "evar/geometry/polyline.hpp"

namespace evar::sim {
namespace {

using geometry::Polyline;

Polyline without_duplicates(const Polyline& points) {
  Polyline out;
  out.reserve(points.size());
  for (const auto& p : points) {
    if (!p.allFinite()) throw std::invalid_argument("tube_mesh: centerline has a non-finite point");
    if (out.empty() || (p - out.back()).norm() > 0.0) out.push_back(p);
  }
  if (out.size() < 2) throw std::invalid_argument("tube_mesh: centerline needs 2 distinct points");
  return out;
}

void check_options(const TubeOptions& options) {
  if (options.segments_around < 3)
    throw std::invalid_argument("tube_mesh: segments_around must be >= 3, got " +
                                std::to_string(options.segments_around));
  if (!(options.ring_spacing_mm > 0.0) || !std::isfinite(options.ring_spacing_mm))
    throw std::invalid_argument("tube_mesh: ring_spacing_mm must be positive and finite");
}

// Intervals between rings: the requested spacing rounded so both ends get a ring. The
// vertex and face counts must fit the int indices of Faces.
int ring_intervals(double length_mm, const TubeOptions& options) {
  const double n = std::max(1.0, std::round(length_mm / options.ring_spacing_mm));
  if (!(2.0 * (n + 1.0) * options.segments_around + 2.0 * options.segments_around < 2147483647.0))
    throw std::invalid_argument("tube_mesh: ring spacing " + std::to_string(options.ring_spacing_mm) +
                                " mm too small for a " + std::to_string(length_mm) + " mm tube (index overflow)");
  return static_cast<int>(n);
}

}  // namespace

int tube_vertex_count(double length_mm, const TubeOptions& options) {
  check_options(options);
  if (!(length_mm > 0.0) || !std::isfinite(length_mm))
    throw std::invalid_argument("tube_vertex_count: length must be positive and finite");
  const int rings = ring_intervals(length_mm, options) + 1;
  return rings * options.segments_around + (options.capped ? 2 : 0);
}

geometry::TriangleMesh tube_mesh(const std::vector<Eigen::Vector3d>& centerline,
                                 const RadiusProfile& radius, const TubeOptions& options) {
  check_options(options);
  if (!radius) throw std::invalid_argument("tube_mesh: empty radius profile");
  const Polyline points = without_duplicates(centerline);
  const std::vector<double> arc = geometry::arc_lengths(points);
  const double length = arc.back();
  const int intervals = ring_intervals(length, options);
  const int rings = intervals + 1;
  const int n = options.segments_around;

  Polyline centres(static_cast<std::size_t>(rings));
  std::vector<double> radii(static_cast<std::size_t>(rings));
  for (int k = 0; k < rings; ++k) {
    // The last ring sits exactly on the end point (no rounding drift).
    const double s = k == intervals ? length : length * k / intervals;
    centres[static_cast<std::size_t>(k)] = k == intervals ? points.back() : geometry::point_at(points, arc, s);
    const double r = radius(s);
    if (!(r > 0.0) || !std::isfinite(r))
      throw std::invalid_argument("tube_mesh: radius must be positive and finite, got " + std::to_string(r) +
                                  " mm at arc length " + std::to_string(s) + " mm");
    radii[static_cast<std::size_t>(k)] = r;
  }
  const std::vector<geometry::Frame> frames = geometry::rotation_minimizing_frames(centres);

  const Eigen::Index nv = static_cast<Eigen::Index>(rings) * n + (options.capped ? 2 : 0);
  const Eigen::Index nf = 2 * static_cast<Eigen::Index>(intervals) * n + (options.capped ? 2 * n : 0);
  geometry::TriangleMesh mesh;
  mesh.V.resize(nv, 3);
  mesh.F.resize(nf, 3);

  // Odd rings are turned by half a segment: with spacing ~ sqrt(3)/2 edge this gives
  // near-equilateral triangles instead of right triangles split from quads.
  const double step = 2.0 * std::numbers::pi / n;
  for (int k = 0; k < rings; ++k) {
    const auto& f = frames[static_cast<std::size_t>(k)];
    const Eigen::Vector3d binormal = f.tangent.cross(f.normal);
    const double offset = (k % 2) * 0.5 * step;
    const double r = radii[static_cast<std::size_t>(k)];
    for (int j = 0; j < n; ++j) {
      const double a = offset + j * step;
      mesh.V.row(static_cast<Eigen::Index>(k) * n + j) =
          (centres[static_cast<std::size_t>(k)] + r * (std::cos(a) * f.normal + std::sin(a) * binormal)).transpose();
    }
  }

  // Angles grow counter-clockwise about the tangent, so (earlier, later, next ring) on
  // the lower ring and (earlier, lower ring, later) on the upper ring face outward.
  Eigen::Index face = 0;
  auto add = [&](int a, int b, int c) { mesh.F.row(face++) << a, b, c; };
  for (int k = 0; k < intervals; ++k) {
    const int lo = k * n, hi = (k + 1) * n;
    for (int j = 0; j < n; ++j) {
      const int j1 = (j + 1) % n;
      if (k % 2 == 0) {  // upper vertex j lies between lower j and j+1
        add(lo + j, lo + j1, hi + j);
        add(hi + j, lo + j1, hi + j1);
      } else {  // lower vertex j lies between upper j and j+1
        add(hi + j, lo + j, hi + j1);
        add(lo + j, lo + j1, hi + j1);
      }
    }
  }
  if (options.capped) {
    const int c0 = rings * n, c1 = rings * n + 1, last = intervals * n;
    mesh.V.row(c0) = centres.front().transpose();
    mesh.V.row(c1) = centres.back().transpose();
    for (int j = 0; j < n; ++j) {
      const int j1 = (j + 1) % n;
      add(c0, j1, j);                // start cap faces back along the tangent
      add(c1, last + j, last + j1);  // end cap faces forward
    }
  }
  return mesh;
}

geometry::TriangleMesh tube_mesh(const std::vector<Eigen::Vector3d>& centerline, const std::vector<double>& radii,
                                 const TubeOptions& options) {
  if (radii.size() != centerline.size())
    throw std::invalid_argument("tube_mesh: " + std::to_string(radii.size()) + " radii for " +
                                std::to_string(centerline.size()) + " centerline points");
  // Arc length of every input point (duplicates included) so radii stay paired with points.
  const std::vector<double> arc = geometry::arc_lengths(centerline);
  auto profile = [&arc, &radii](double s) { return interpolate_along(arc, radii, s); };
  return tube_mesh(centerline, RadiusProfile(profile), options);
}

TubeOptions tube_options_for_vertex_count(double length_mm, double mean_radius_mm, int target_vertices,
                                          bool capped) {
  if (!(length_mm > 0.0) || !std::isfinite(length_mm) || !(mean_radius_mm > 0.0) || !std::isfinite(mean_radius_mm))
    throw std::invalid_argument("tube_options_for_vertex_count: length and radius must be positive and finite");
  const int caps = capped ? 2 : 0;
  if (target_vertices < 6 + caps)
    throw std::invalid_argument("tube_options_for_vertex_count: target of " + std::to_string(target_vertices) +
                                " vertices is below 2 rings of 3");
  // Equilateral: spacing h = sqrt(3)/2 * 2 r sin(pi/N) ~ sqrt(3) pi r / N, and the vertex
  // count is N * (L / h + 1), so N^2 ~ V sqrt(3) pi r / L for long tubes.
  const double target = target_vertices - caps;
  const double n_est = std::sqrt(target * std::sqrt(3.0) * std::numbers::pi * mean_radius_mm / length_mm);
  const int n = std::clamp(static_cast<int>(std::lround(n_est)), 3, static_cast<int>(target / 2.0));
  const int rings = std::max(2, static_cast<int>(std::lround(target / n)));
  TubeOptions options;
  options.segments_around = n;
  options.ring_spacing_mm = length_mm / (rings - 1);
  options.capped = capped;
  return options;
}

TubeOptions tube_options_for_vertex_count(const std::vector<Eigen::Vector3d>& centerline,
                                          const RadiusProfile& radius, int target_vertices, bool capped) {
  if (!radius) throw std::invalid_argument("tube_options_for_vertex_count: empty radius profile");
  const Polyline points = without_duplicates(centerline);
  const double length = geometry::arc_lengths(points).back();
  // Arc-length mean radius by the trapezoid rule on ~0.5 mm steps.
  const int steps = std::clamp(static_cast<int>(std::ceil(length / 0.5)), 16, 1 << 20);
  double sum = 0.0;
  for (int i = 0; i <= steps; ++i) {
    const double w = (i == 0 || i == steps) ? 0.5 : 1.0;
    sum += w * radius(length * i / steps);
  }
  return tube_options_for_vertex_count(length, sum / steps, target_vertices, capped);
}

double interpolate_along(const std::vector<double>& arc, const std::vector<double>& values, double s) {
  const auto it = std::upper_bound(arc.begin(), arc.end(), s);
  if (it == arc.begin()) return values.front();
  if (it == arc.end()) return values.back();
  const auto i = static_cast<std::size_t>(it - arc.begin());
  const double len = arc[i] - arc[i - 1];
  const double u = len > 0.0 ? (s - arc[i - 1]) / len : 1.0;
  return (1.0 - u) * values[i - 1] + u * values[i];
}

}  // namespace evar::sim
