#include "evar/geometry/polyline.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace evar::geometry {

std::vector<double> arc_lengths(const Polyline& points) {
  std::vector<double> s(points.size(), 0.0);
  for (std::size_t i = 1; i < points.size(); ++i) s[i] = s[i - 1] + (points[i] - points[i - 1]).norm();
  return s;
}

Eigen::Vector3d point_at(const Polyline& points, const std::vector<double>& arc, double s) {
  if (points.size() == 1) return points.front();
  s = std::clamp(s, 0.0, arc.back());
  const auto it = std::upper_bound(arc.begin(), arc.end(), s);
  std::size_t i = static_cast<std::size_t>(std::max<std::ptrdiff_t>(1, it - arc.begin()));
  i = std::min(i, points.size() - 1);
  const double len = arc[i] - arc[i - 1];
  const double u = len > 0.0 ? (s - arc[i - 1]) / len : 0.0;
  return (1.0 - u) * points[i - 1] + u * points[i];
}

Eigen::Vector3d tangent_at(const Polyline& points, const std::vector<double>& arc, double s) {
  if (points.size() < 2) throw std::invalid_argument("tangent_at: polyline needs 2 points");
  s = std::clamp(s, 0.0, arc.back());
  const auto it = std::upper_bound(arc.begin(), arc.end(), s);
  std::size_t i = static_cast<std::size_t>(std::max<std::ptrdiff_t>(1, it - arc.begin()));
  i = std::min(i, points.size() - 1);
  // Skip zero-length segments in either direction.
  for (std::size_t j = i; j < points.size(); ++j) {
    const Eigen::Vector3d d = points[j] - points[j - 1];
    if (d.norm() > 0.0) return d.normalized();
  }
  for (std::size_t j = i; j >= 1; --j) {
    const Eigen::Vector3d d = points[j] - points[j - 1];
    if (d.norm() > 0.0) return d.normalized();
  }
  throw std::invalid_argument("tangent_at: polyline has no extent");
}

namespace {

// A polyline about to be sampled every `step_mm`: its points without consecutive
// duplicates, their arc lengths, and how many whole steps its length holds.
struct Sampling {
  Polyline unique;
  std::vector<double> arc;
  double length = 0.0;
  std::size_t steps = 0;
};

Sampling prepare_sampling(const Polyline& points, double step_mm) {
  if (!(step_mm > 0.0)) throw std::invalid_argument("resample: step must be positive");
  Sampling s;
  for (const auto& p : points)
    if (s.unique.empty() || (p - s.unique.back()).norm() > 0.0) s.unique.push_back(p);
  if (s.unique.size() < 2) return s;
  s.arc = arc_lengths(s.unique);
  s.length = s.arc.back();
  const double count = std::floor(s.length / step_mm);
  if (!(count < 1e7)) throw std::invalid_argument("resample: more than 10 million samples requested");
  s.steps = static_cast<std::size_t>(count);
  return s;
}

}  // namespace

Polyline resample(const Polyline& points, double step_mm) {
  const Sampling s = prepare_sampling(points, step_mm);
  if (s.unique.size() < 2) return s.unique;
  Polyline out;
  out.reserve(s.steps + 2);
  for (std::size_t k = 0; k <= s.steps; ++k) out.push_back(point_at(s.unique, s.arc, static_cast<double>(k) * step_mm));
  if (s.length - static_cast<double>(s.steps) * step_mm > 1e-9 * std::max(1.0, s.length)) out.push_back(s.unique.back());
  return out;
}

Polyline resample_symmetric(const Polyline& points, double step_mm) {
  const Sampling s = prepare_sampling(points, step_mm);
  if (s.unique.size() < 2) return s.unique;
  const double margin = 0.5 * (s.length - static_cast<double>(s.steps) * step_mm);
  const double apart = 1e-9 * std::max(1.0, s.length);
  Polyline out;
  out.reserve(s.steps + 3);
  out.push_back(s.unique.front());
  for (std::size_t k = 0; k <= s.steps; ++k) {
    const Eigen::Vector3d p = point_at(s.unique, s.arc, margin + static_cast<double>(k) * step_mm);
    if ((p - out.back()).norm() > apart) out.push_back(p);
  }
  if ((s.unique.back() - out.back()).norm() > apart) out.push_back(s.unique.back());
  return out;
}

PolylineProjector::PolylineProjector(const Polyline& points) : points_(&points) {
  if (points.size() < 2) throw std::invalid_argument("project_onto: polyline needs 2 points");
  length_.resize(points.size() - 1);
  arc_.resize(points.size() - 1);
  double s = 0.0;
  for (std::size_t i = 0; i + 1 < points.size(); ++i) {
    length_[i] = (points[i + 1] - points[i]).norm();
    arc_[i] = s;
    s += length_[i];
  }
}

PolylineProjection PolylineProjector::project(const Eigen::Vector3d& query, int hint, int* segment_out) const {
  const Polyline& points = *points_;
  const std::size_t segments = length_.size();
  PolylineProjection best{};
  double best_d2 = std::numeric_limits<double>::infinity();
  double best_d = best_d2;
  std::size_t best_i = segments;
  const auto consider = [&](std::size_t i) {
    const double len = length_[i];
    if (len == 0.0) return;
    const Eigen::Vector3d& a = points[i];
    const Eigen::Vector3d d = points[i + 1] - a;
    const double u_raw = (query - a).dot(d) / d.squaredNorm();
    const double u = std::clamp(u_raw, 0.0, 1.0);
    const Eigen::Vector3d p = a + u * d;
    const double dist2 = (query - p).squaredNorm();
    // The first segment in order wins ties, as a plain scan would choose.
    if (dist2 < best_d2 || (dist2 == best_d2 && i < best_i)) {
      best_d2 = dist2;
      best_d = std::sqrt(dist2);
      best_i = i;
      best.point = p;
      best.arc_length_mm = arc_[i] + u * len;
      best.tangent = d / len;
      best.beyond_start = (i == 0 && u_raw < 0.0);
      best.beyond_end = (i + 1 == segments && u_raw > 1.0);
    }
  };
  if (hint >= 0 && static_cast<std::size_t>(hint) < segments) consider(static_cast<std::size_t>(hint));
  for (std::size_t i = 0; i < segments; ++i) {
    // No point of the segment is nearer than |query − a| − len: rule it out when that
    // exceeds the best distance so far (strictly, so ties are still compared).
    const double reach = length_[i] + best_d;
    if ((query - points[i]).squaredNorm() > reach * reach) continue;
    consider(i);
  }
  if (best_i == segments) throw std::invalid_argument("project_onto: polyline has no extent");
  best.distance_mm = best_d;
  if (segment_out) *segment_out = static_cast<int>(best_i);
  return best;
}

std::vector<Eigen::Vector2d> resample_2d(const std::vector<Eigen::Vector2d>& pts, double step) {
  if (pts.size() < 2) return pts;
  if (!(step > 0.0)) throw std::invalid_argument("resample_2d: step must be > 0");
  std::vector<double> s(pts.size(), 0.0);
  for (std::size_t i = 1; i < pts.size(); ++i) s[i] = s[i - 1] + (pts[i] - pts[i - 1]).norm();
  const double length = s.back();
  if (!(length > 0.0)) return {pts.front()};
  const int n = std::max(2, static_cast<int>(std::ceil(length / step)) + 1);
  std::vector<Eigen::Vector2d> even(static_cast<std::size_t>(n));
  std::size_t k = 0;
  for (int i = 0; i < n; ++i) {
    const double t = length * i / (n - 1);
    while (k + 2 < s.size() && s[k + 1] < t) ++k;
    const double seg = s[k + 1] - s[k];
    const double u = seg > 0.0 ? std::clamp((t - s[k]) / seg, 0.0, 1.0) : 0.0;
    even[static_cast<std::size_t>(i)] = pts[k] + u * (pts[k + 1] - pts[k]);
  }
  return even;
}

double distance_to_polyline_2d(const Eigen::Vector2d& p, const std::vector<Eigen::Vector2d>& line) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    const Eigen::Vector2d d = line[i + 1] - line[i];
    const double t = std::clamp((p - line[i]).dot(d) / std::max(d.squaredNorm(), 1e-300), 0.0, 1.0);
    best = std::min(best, (p - line[i] - t * d).norm());
  }
  return best;
}

PolylineProjection project_onto(const Polyline& points, const Eigen::Vector3d& query) {
  return PolylineProjector(points).project(query);
}

std::vector<Frame> rotation_minimizing_frames(const Polyline& points) {
  const std::size_t n = points.size();
  if (n < 2) throw std::invalid_argument("rotation_minimizing_frames: polyline needs 2 points");
  std::vector<Eigen::Vector3d> t(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d d = (i + 1 < n ? points[i + 1] : points[i]) - (i > 0 ? points[i - 1] : points[i]);
    t[i] = d.norm() > 0.0 ? d.normalized() : (i > 0 ? t[i - 1] : Eigen::Vector3d::UnitZ());
  }
  std::vector<Frame> frames(n);
  // Initial normal: any unit vector orthogonal to t0, taken from the least aligned axis.
  Eigen::Vector3d axis = Eigen::Vector3d::UnitX();
  if (std::abs(t[0].x()) > 0.9) axis = Eigen::Vector3d::UnitY();
  frames[0] = {t[0], (axis - axis.dot(t[0]) * t[0]).normalized()};
  for (std::size_t i = 0; i + 1 < n; ++i) {
    // Double reflection (Wang, Juettler, Zheng, Liu 2008).
    const Eigen::Vector3d v1 = points[i + 1] - points[i];
    const double c1 = v1.squaredNorm();
    Eigen::Vector3d r = frames[i].normal, ti = frames[i].tangent;
    if (c1 > 0.0) {
      r -= (2.0 / c1) * v1.dot(r) * v1;
      ti -= (2.0 / c1) * v1.dot(ti) * v1;
    }
    const Eigen::Vector3d v2 = t[i + 1] - ti;
    const double c2 = v2.squaredNorm();
    if (c2 > 0.0) r -= (2.0 / c2) * v2.dot(r) * v2;
    r -= r.dot(t[i + 1]) * t[i + 1];
    frames[i + 1] = {t[i + 1], r.normalized()};
  }
  return frames;
}

}  // namespace evar::geometry
