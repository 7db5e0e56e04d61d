#include "evar/geometry/two_view_reconstruction.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <numbers>

namespace evar::geometry {

namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

struct Curve2 {
  std::vector<Eigen::Vector2d> p;
  std::vector<double> s;  // arc length (px)
};

Curve2 resample2(const std::vector<Eigen::Vector2d>& in, double step) {
  Curve2 c{resample_2d(in, step), {}};
  double s = 0.0;
  for (std::size_t i = 0; i < c.p.size(); ++i) {
    if (i > 0) s += (c.p[i] - c.p[i - 1]).norm();
    c.s.push_back(s);
  }
  return c;
}

double line_distance(const Eigen::Vector3d& l, const Eigen::Vector2d& x) {
  return std::abs(l.dot(x.homogeneous())) / std::max(l.head<2>().norm(), 1e-300);
}

}  // namespace

double view_separation_deg(const ProjectionMatrix& P1, const ProjectionMatrix& P2) {
  const Eigen::Vector3d d1 = pinhole_camera(P1).direction, d2 = pinhole_camera(P2).direction;
  return std::acos(std::clamp(d1.dot(d2), -1.0, 1.0)) * kRadToDeg;
}

Eigen::Matrix3d fundamental_matrix(const ProjectionMatrix& P1, const ProjectionMatrix& P2) {
  const Eigen::Vector3d C1 = pinhole_camera(P1).source_mm;
  const Eigen::Vector3d e2 = P2 * C1.homogeneous();
  Eigen::Matrix3d ex;
  ex << 0, -e2.z(), e2.y(), e2.z(), 0, -e2.x(), -e2.y(), e2.x(), 0;
  const Eigen::Matrix<double, 4, 3> P1_pinv = P1.transpose() * (P1 * P1.transpose()).inverse();
  return ex * P2 * P1_pinv;
}

Eigen::Vector3d triangulate(const ProjectionMatrix& P1, const Eigen::Vector2d& x1, const ProjectionMatrix& P2,
                            const Eigen::Vector2d& x2) {
  // Rows scaled to unit norm so pixels and millimetres weigh alike.
  Eigen::Matrix4d A;
  A.row(0) = x1.x() * P1.row(2) - P1.row(0);
  A.row(1) = x1.y() * P1.row(2) - P1.row(1);
  A.row(2) = x2.x() * P2.row(2) - P2.row(0);
  A.row(3) = x2.y() * P2.row(2) - P2.row(1);
  for (int r = 0; r < 4; ++r) A.row(r).normalize();
  const Eigen::JacobiSVD<Eigen::Matrix4d> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d X = svd.matrixV().col(3);
  return X.head<3>() / X.w();
}

namespace {

// A local alignment of the resampled curves, both indices advancing:
// S(i,j) = reward(i,j) + max(0, S(i−1,j−1), S(i−1,j), S(i,j−1)), each matched pair scoring
// its mean epipolar distance (px) against the reward β.
struct Alignment {
  float score = 0.0f;
  int bi = -1, bj = -1;               // where the best local alignment ends
  std::vector<std::uint8_t> from;     // 0 start, 1 diagonal, 2 from i−1, 3 from j−1
};

Alignment align(const Curve2& c1, const Curve2& c2, const std::vector<Eigen::Vector3d>& l2, const Eigen::Matrix3d& F,
                double beta, std::vector<float>& S) {
  const int N = static_cast<int>(c1.p.size()), M = static_cast<int>(c2.p.size());
  std::vector<Eigen::Vector3d> l1(static_cast<std::size_t>(M));
  for (int j = 0; j < M; ++j) l1[static_cast<std::size_t>(j)] = F.transpose() * c2.p[static_cast<std::size_t>(j)].homogeneous();
  Alignment a;
  a.from.resize(static_cast<std::size_t>(N) * static_cast<std::size_t>(M));
  S.resize(a.from.size());
  const auto at = [&](int i, int j) { return S[static_cast<std::size_t>(i) * static_cast<std::size_t>(M) + static_cast<std::size_t>(j)]; };
  for (int i = 0; i < N; ++i)
    for (int j = 0; j < M; ++j) {
      const double d = 0.5 * (line_distance(l2[static_cast<std::size_t>(i)], c2.p[static_cast<std::size_t>(j)]) +
                              line_distance(l1[static_cast<std::size_t>(j)], c1.p[static_cast<std::size_t>(i)]));
      const float reward = static_cast<float>(beta - std::min(d, 4.0 * beta));
      float prev = 0.0f;
      std::uint8_t f = 0;
      if (i > 0 && j > 0 && at(i - 1, j - 1) > prev) prev = at(i - 1, j - 1), f = 1;
      if (i > 0 && at(i - 1, j) > prev) prev = at(i - 1, j), f = 2;
      if (j > 0 && at(i, j - 1) > prev) prev = at(i, j - 1), f = 3;
      const std::size_t k = static_cast<std::size_t>(i) * static_cast<std::size_t>(M) + static_cast<std::size_t>(j);
      S[k] = prev + reward;
      a.from[k] = f;
      if (S[k] > a.score) a.score = S[k], a.bi = i, a.bj = j;
    }
  return a;
}

// The 3D curve of one alignment (steps 3-5 of the header).
Reconstruction triangulated(const Curve2& c1, const Curve2& c2, const std::vector<Eigen::Vector3d>& l2, const Alignment& al,
                            const ProjectionMatrix& P1, const ProjectionMatrix& P2, const std::vector<Eigen::Vector2d>& curve1,
                            const ReconstructionOptions& o) {
  const int N = static_cast<int>(c1.p.size()), M = static_cast<int>(c2.p.size());
  Reconstruction out;
  out.alignment_score = al.score;
  if (al.bi < 0) throw ReconstructionError("the curves do not correspond in these views (no epipolar match)");
  // Back-track: for each matched i, the mean of its matched j.
  std::vector<double> j_of(static_cast<std::size_t>(N), -1.0);
  std::vector<int> j_count(static_cast<std::size_t>(N), 0);
  int i_first = al.bi, j_first = al.bj;
  for (int i = al.bi, j = al.bj;;) {
    j_of[static_cast<std::size_t>(i)] = (j_of[static_cast<std::size_t>(i)] < 0 ? 0.0 : j_of[static_cast<std::size_t>(i)]) + j;
    ++j_count[static_cast<std::size_t>(i)];
    i_first = i;
    j_first = j;
    const std::uint8_t f = al.from[static_cast<std::size_t>(i) * static_cast<std::size_t>(M) + static_cast<std::size_t>(j)];
    if (f == 0) break;
    if (f == 1) --i, --j;
    else if (f == 2) --i;
    else --j;
  }
  out.matched_fraction_1 = (c1.s[static_cast<std::size_t>(al.bi)] - c1.s[static_cast<std::size_t>(i_first)]) / std::max(c1.s.back(), 1e-9);
  out.matched_fraction_2 = (c2.s[static_cast<std::size_t>(al.bj)] - c2.s[static_cast<std::size_t>(j_first)]) / std::max(c2.s.back(), 1e-9);
  if (al.bi - i_first < 4)
    throw ReconstructionError("the curves do not correspond in these views: fewer than 5 points of view 1 match view 2 "
                              "(a different device, or geometry that does not belong to these frames?)");

  // Sub-pixel crossings, reliability, triangulation (depth along view 1's rays).
  const PinholeCamera cam1 = pinhole_camera(P1);
  const double grazing_sin = std::sin(o.grazing_deg / kRadToDeg);
  std::vector<double> depth, arc;
  std::vector<char> ok;
  std::vector<Eigen::Vector3d> rays;
  for (int i = i_first; i <= al.bi; ++i) {
    const auto& u = c1.p[static_cast<std::size_t>(i)];
    const Eigen::Vector3d& l = l2[static_cast<std::size_t>(i)];
    const double jm = j_of[static_cast<std::size_t>(i)] / j_count[static_cast<std::size_t>(i)];
    const Eigen::Vector2d line_dir = Eigen::Vector2d(-l.y(), l.x()).normalized();
    bool found = false, reliable = false;
    Eigen::Vector2d v;
    double best_gap = std::numeric_limits<double>::infinity();
    const int k0 = std::max(0, static_cast<int>(std::floor(jm)) - 4), k1 = std::min(M - 2, static_cast<int>(std::ceil(jm)) + 4);
    for (int k = k0; k <= k1; ++k) {
      const Eigen::Vector2d a = c2.p[static_cast<std::size_t>(k)], b = c2.p[static_cast<std::size_t>(k + 1)];
      const double fa = l.dot(a.homogeneous()), fb = l.dot(b.homogeneous());
      if (fa * fb > 0.0 || fa == fb) continue;
      const double t = fa / (fa - fb);
      const double gap = std::abs(k + t - jm);
      if (gap < best_gap) {
        best_gap = gap;
        v = a + t * (b - a);
        found = true;
        const Eigen::Vector2d tangent = (b - a).normalized();
        reliable = std::abs(tangent.x() * line_dir.y() - tangent.y() * line_dir.x()) >= grazing_sin;
      }
    }
    const Eigen::Vector3d ray = back_projected_ray(cam1, u);
    rays.push_back(ray);
    arc.push_back(c1.s[static_cast<std::size_t>(i)]);
    if (found && reliable) {
      const Eigen::Vector3d X = triangulate(P1, u, P2, v);
      depth.push_back((X - cam1.source_mm).dot(ray));
      ok.push_back(X.allFinite() && depth.back() > 0.0);
    } else {
      depth.push_back(0.0);
      ok.push_back(0);
    }
  }
  const auto n = depth.size();
  std::size_t first = n, last = 0;
  for (std::size_t k = 0; k < n; ++k)
    if (ok[k]) first = std::min(first, k), last = k;
  if (first == n)
    throw ReconstructionError("no reliable correspondence: in these two views the device runs along the epipolar lines "
                              "everywhere (choose views whose rotation axis is not along the device)");
  // Where the device runs along the epipolar lines its depth is not measured. Between
  // reliable points it is interpolated along arc length; beyond the outermost ones nothing
  // is made up (a held depth can be tens of mm wrong and still reproject onto both curves,
  // since a point along its ray only slides along the epipolar line in view 2).
  for (std::size_t k = first; k <= last; ++k) {
    if (ok[k]) continue;
    std::size_t a = k, b = k;
    while (!ok[a]) --a;
    while (!ok[b]) ++b;
    depth[k] = depth[a] + (depth[b] - depth[a]) * (arc[k] - arc[a]) / std::max(arc[b] - arc[a], 1e-12);
  }
  std::vector<Eigen::Vector3d> X(n);
  for (std::size_t k = first; k <= last; ++k) X[k] = cam1.source_mm + depth[k] * rays[k];
  // An interpolated stretch longer than max_gap_mm (its length along the filled curve, a
  // lower bound of the true one) is not trusted: the curve is cut there and the longest
  // piece kept.
  std::size_t best0 = first, best1 = first, p0 = first, prev = first;  // prev: the last reliable point
  double best_mm = -1.0, piece_mm = 0.0;
  for (std::size_t k = first + 1; k <= last; ++k) {
    if (!ok[k]) continue;
    double stretch_mm = 0.0;
    for (std::size_t m = prev + 1; m <= k; ++m) stretch_mm += (X[m] - X[m - 1]).norm();
    if (k > prev + 1 && stretch_mm > o.max_gap_mm) {
      if (piece_mm > best_mm) best_mm = piece_mm, best0 = p0, best1 = prev;
      p0 = k;
      piece_mm = 0.0;
    } else {
      piece_mm += stretch_mm;
    }
    prev = k;
  }
  if (piece_mm > best_mm) best0 = p0, best1 = last;
  const double matched_px = arc[n - 1] - arc[0];
  out.kept_fraction = matched_px > 0.0 ? (arc[best1] - arc[best0]) / matched_px : 1.0;
  if (best1 <= best0)
    throw ReconstructionError("no reliable stretch of device: its depth is measured at isolated points only, the device "
                              "running along the epipolar lines between them (choose views whose rotation axis is not "
                              "along the device)");
  X = std::vector<Eigen::Vector3d>(X.begin() + static_cast<std::ptrdiff_t>(best0), X.begin() + static_cast<std::ptrdiff_t>(best1) + 1);
  ok = std::vector<char>(ok.begin() + static_cast<std::ptrdiff_t>(best0), ok.begin() + static_cast<std::ptrdiff_t>(best1) + 1);
  const std::size_t kept = X.size();

  // Smoothing along 3D arc length, the window shrinking towards the ends.
  std::vector<double> s3(kept, 0.0);
  for (std::size_t k = 1; k < kept; ++k) s3[k] = s3[k - 1] + (X[k] - X[k - 1]).norm();
  std::vector<Eigen::Vector3d> Xs(kept);
  for (std::size_t k = 0; k < kept; ++k) {
    if (!(o.smoothing_mm > 0.0)) {
      Xs[k] = X[k];
      continue;
    }
    const double reach = std::min({3.0 * o.smoothing_mm, s3[k] - s3.front(), s3.back() - s3[k]});
    Eigen::Vector3d acc = Eigen::Vector3d::Zero();
    double wsum = 0.0;
    for (std::size_t m = k; m < kept && s3[m] - s3[k] <= reach; ++m) {
      const double w = std::exp(-0.5 * std::pow((s3[m] - s3[k]) / o.smoothing_mm, 2));
      acc += w * X[m];
      wsum += w;
    }
    for (std::size_t m = k; m-- > 0 && s3[k] - s3[m] <= reach;) {
      const double w = std::exp(-0.5 * std::pow((s3[k] - s3[m]) / o.smoothing_mm, 2));
      acc += w * X[m];
      wsum += w;
    }
    Xs[k] = acc / wsum;
  }
  // Even resampling, reliability from the nearest sample, residuals.
  Polyline smoothed(Xs.begin(), Xs.end());
  std::vector<double> ss(kept, 0.0);
  for (std::size_t k = 1; k < kept; ++k) ss[k] = ss[k - 1] + (Xs[k] - Xs[k - 1]).norm();
  out.points = resample(smoothed, o.output_step_mm);
  std::size_t cursor = 0;
  double s_out = 0.0;
  for (std::size_t k = 0; k < out.points.size(); ++k) {
    if (k > 0) s_out += (out.points[k] - out.points[k - 1]).norm();
    while (cursor + 1 < kept && ss[cursor + 1] <= s_out) ++cursor;
    const std::size_t nearest = (cursor + 1 < kept && ss[cursor + 1] - s_out < s_out - ss[cursor]) ? cursor + 1 : cursor;
    out.reliable.push_back(ok[nearest]);
    const auto x1 = project(P1, out.points[k]), x2 = project(P2, out.points[k]);
    const double r = (x1 && x2) ? std::max(distance_to_polyline_2d(*x1, curve1), distance_to_polyline_2d(*x2, c2.p))
                                : std::numeric_limits<double>::infinity();
    out.residual_px.push_back(r);
  }
  double sum = 0.0;
  for (const double r : out.residual_px) {
    sum += r;
    out.max_residual_px = std::max(out.max_residual_px, r);
  }
  out.mean_residual_px = sum / static_cast<double>(out.residual_px.size());
  out.reliable_fraction = static_cast<double>(std::count(out.reliable.begin(), out.reliable.end(), 1)) /
                          static_cast<double>(out.reliable.size());
  return out;
}

}  // namespace

std::vector<Reconstruction> reconstruct_two_view_readings(const std::vector<Eigen::Vector2d>& curve1, const ProjectionMatrix& P1,
                                                          const std::vector<Eigen::Vector2d>& curve2, const ProjectionMatrix& P2,
                                                          const ReconstructionOptions& o) {
  if (curve1.size() < 2 || curve2.size() < 2)
    throw ReconstructionError("two-view reconstruction: each view needs a curve of at least 2 points (view " +
                              std::string(curve1.size() < 2 ? "1" : "2") + " has " +
                              std::to_string(std::min(curve1.size(), curve2.size())) + ")");
  for (const auto* c : {&curve1, &curve2})
    for (const auto& p : *c)
      if (!p.allFinite()) throw ReconstructionError("two-view reconstruction: a curve point is not finite");
  if (!(o.sample_step_px > 0.0) || !(o.match_reward_px > 0.0) || !(o.output_step_mm > 0.0) || !(o.smoothing_mm >= 0.0) ||
      !(o.min_separation_deg > 0.0 && o.min_separation_deg < 90.0) || !(o.grazing_deg >= 0.0 && o.grazing_deg < 90.0) ||
      !(o.max_gap_mm > 0.0) || !(o.ambiguity_ratio > 0.0 && o.ambiguity_ratio <= 1.0) || !std::isfinite(o.sample_step_px) ||
      !std::isfinite(o.match_reward_px) || !std::isfinite(o.output_step_mm) || !std::isfinite(o.smoothing_mm))
    throw std::invalid_argument(
        "two-view reconstruction: sample step, match reward, output step and max gap must be finite and > 0, smoothing >= 0, "
        "min separation in (0, 90), grazing angle in [0, 90), ambiguity ratio in (0, 1]");
  double separation = 0.0;
  try {
    separation = view_separation_deg(P1, P2);
  } catch (const std::invalid_argument& e) {  // a singular projection
    throw ReconstructionError(std::string("two-view reconstruction: ") + e.what());
  }
  // Views facing each other (near 180°) triangulate as badly as views side by side.
  const double effective = std::min(separation, 180.0 - separation);
  if (effective < o.min_separation_deg)
    throw ReconstructionError("the views are " + std::to_string(separation).substr(0, 5) +
                              " degrees apart; their rays must cross at " + std::to_string(o.min_separation_deg).substr(0, 5) +
                              " degrees or more (between that and 180 minus that) to triangulate: rotate the C-arm "
                              "differently between the two frames");

  // Matching is N × M: refuse curves absurdly long for an image (a stray point).
  double length1 = 0.0, length2 = 0.0;
  for (std::size_t i = 1; i < curve1.size(); ++i) length1 += (curve1[i] - curve1[i - 1]).norm();
  for (std::size_t i = 1; i < curve2.size(); ++i) length2 += (curve2[i] - curve2[i - 1]).norm();
  if ((length1 / o.sample_step_px + 1.0) * (length2 / o.sample_step_px + 1.0) > 2e7)
    throw ReconstructionError("two-view reconstruction: the curves are " + std::to_string(static_cast<long>(length1)) +
                              " and " + std::to_string(static_cast<long>(length2)) +
                              " px long; more than fits any detector (a stray point?)");

  const Curve2 c1 = resample2(curve1, o.sample_step_px);
  const Curve2 c2 = resample2(curve2, o.sample_step_px);
  const Curve2 c2_reversed{{c2.p.rbegin(), c2.p.rend()}, c2.s};  // still evenly spaced from 0
  const Eigen::Matrix3d F = fundamental_matrix(P1, P2);
  std::vector<Eigen::Vector3d> l2(c1.p.size());  // view 1's points' epipolar lines in view 2
  for (std::size_t i = 0; i < c1.p.size(); ++i) l2[i] = F * c1.p[i].homogeneous();

  // Both curves should run the same way (tip first), but a segmentation cannot always tell
  // the ends apart (both at the image border), so both readings of curve 2 are aligned.
  // The one that scores higher is the device; when the other scores nearly as well (a
  // shape symmetric about the epipolar geometry: a crossover catheter's two limbs at the
  // same heights in a LAO/RAO pair), both are returned: only the anatomy can tell them apart.
  std::vector<float> S;
  const Alignment forward = align(c1, c2, l2, F, o.match_reward_px, S);
  const Alignment backward = align(c1, c2_reversed, l2, F, o.match_reward_px, S);
  const bool reversed_first = backward.score > forward.score;
  const Alignment& better = reversed_first ? backward : forward;
  const Alignment& worse = reversed_first ? forward : backward;
  std::vector<Reconstruction> readings;
  readings.push_back(triangulated(c1, reversed_first ? c2_reversed : c2, l2, better, P1, P2, curve1, o));
  readings.back().second_curve_reversed = reversed_first;
  if (worse.score >= o.ambiguity_ratio * better.score && worse.bi >= 0) {
    try {
      readings.push_back(triangulated(c1, reversed_first ? c2 : c2_reversed, l2, worse, P1, P2, curve1, o));
      readings.back().second_curve_reversed = !reversed_first;
    } catch (const ReconstructionError&) {
      // That reading gives no curve: no ambiguity.
    }
  }
  for (auto& r : readings) r.separation_deg = separation;
  return readings;
}

Reconstruction reconstruct_two_view(const std::vector<Eigen::Vector2d>& curve1, const ProjectionMatrix& P1,
                                    const std::vector<Eigen::Vector2d>& curve2, const ProjectionMatrix& P2,
                                    const ReconstructionOptions& o) {
  auto readings = reconstruct_two_view_readings(curve1, P1, curve2, P2, o);
  if (readings.size() > 1) {
    char why[256];
    std::snprintf(why, sizeof why,
                  "the device reads two ways in these views (alignment scores %.0f and %.0f): its shape is symmetric "
                  "about their epipolar geometry; choose by the anatomy, or take views turned about another axis",
                  static_cast<double>(readings[0].alignment_score), static_cast<double>(readings[1].alignment_score));
    throw ReconstructionError(why);
  }
  return std::move(readings.front());
}

}  // namespace evar::geometry
