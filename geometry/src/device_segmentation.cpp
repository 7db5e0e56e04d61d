#include "evar/geometry/device_segmentation.hpp"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <queue>
#include <stdexcept>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "evar/geometry/polyline.hpp"

namespace evar::geometry {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// The ridge measure at the best scale, with the across-ridge normal and the Newton offset
// from the pixel to the ridge centre along it.
struct Ridge {
  cv::Mat response;  // CV_32F, noise units
  cv::Mat nx, ny;    // CV_32F unit normal
  cv::Mat offset;    // CV_32F, px along the normal
  cv::Mat contrast;  // CV_32F, the top-hat attenuation (−log units): the device's Δp on its centreline
  cv::Mat attenuation;  // CV_32F, −log(I + 1), lightly smoothed: the background on either side
};

constexpr double kQuantisedFloor = 8.0;  // grey levels

cv::Mat to_float(const cv::Mat& image) {
  if (image.empty()) throw std::invalid_argument("segment_device: empty image");
  if (image.channels() != 1 || (image.depth() != CV_8U && image.depth() != CV_16U && image.depth() != CV_32F))
    throw std::invalid_argument("segment_device: expected a single-channel 8-bit, 16-bit or float image");
  cv::Mat f;
  image.convertTo(f, CV_32F);
  cv::patchNaNs(f, 0.0);
  return f;
}

// The exposed field: rows and columns whose mean intensity is at least 30 % of the
// typical mean of the central half (lead shutters transmit almost nothing).
cv::Rect exposed_field(const cv::Mat& f) {
  cv::Mat col_mean, row_mean;
  cv::reduce(f, col_mean, 0, cv::REDUCE_AVG, CV_32F);
  cv::reduce(f, row_mean, 1, cv::REDUCE_AVG, CV_32F);
  const auto bounds = [](const float* m, int n) -> std::pair<int, int> {
    std::vector<float> centre(m + n / 4, m + std::max(n / 4 + 1, 3 * n / 4));
    std::nth_element(centre.begin(), centre.begin() + static_cast<long>(centre.size() / 2), centre.end());
    const float ref = centre[centre.size() / 2];
    if (!(ref > 0.0f)) return {0, -1};
    int lo = 0, hi = n - 1;
    while (lo < n && m[lo] < 0.3f * ref) ++lo;
    while (hi >= 0 && m[hi] < 0.3f * ref) --hi;
    return {lo, hi};
  };
  const auto [x0, x1] = bounds(col_mean.ptr<float>(0), f.cols);
  const auto [y0, y1] = bounds(row_mean.ptr<float>(0), f.rows);
  if (x1 < x0 || y1 < y0) return {};
  return {x0, y0, x1 - x0 + 1, y1 - y0 + 1};
}

#if defined(__SSE2__)
// exp(x) for x in [−87, 0], four at a time: 2^(x·log2 e) = 2^n · 2^f with the fraction's
// power from its Taylor series to the fifth order (relative error below 2e-4, ample for
// the damping factors).
inline __m128 exp_negative_ps(__m128 x) {
  x = _mm_max_ps(x, _mm_set1_ps(-87.0f));
  const __m128 y = _mm_mul_ps(x, _mm_set1_ps(1.44269504f));
  __m128i n = _mm_cvttps_epi32(y);  // towards zero; y <= 0, so n = ceil(y)
  __m128 nf = _mm_cvtepi32_ps(n);
  const __m128 fix = _mm_and_ps(_mm_cmpgt_ps(nf, y), _mm_set1_ps(1.0f));  // make n = floor(y)
  nf = _mm_sub_ps(nf, fix);
  n = _mm_cvttps_epi32(nf);
  const __m128 f = _mm_sub_ps(y, nf);  // in [0, 1)
  __m128 p = _mm_set1_ps(0.0013333558f);
  p = _mm_add_ps(_mm_mul_ps(p, f), _mm_set1_ps(0.0096181291f));
  p = _mm_add_ps(_mm_mul_ps(p, f), _mm_set1_ps(0.0555041087f));
  p = _mm_add_ps(_mm_mul_ps(p, f), _mm_set1_ps(0.2402265070f));
  p = _mm_add_ps(_mm_mul_ps(p, f), _mm_set1_ps(0.6931471806f));
  p = _mm_add_ps(_mm_mul_ps(p, f), _mm_set1_ps(1.0f));
  const __m128i bits = _mm_slli_epi32(_mm_add_epi32(n, _mm_set1_epi32(127)), 23);
  return _mm_mul_ps(p, _mm_castsi128_ps(bits));
}

inline __m128 select_ps(__m128 mask, __m128 if_true, __m128 if_false) {
  return _mm_or_ps(_mm_and_ps(mask, if_true), _mm_andnot_ps(mask, if_false));
}

// The ridge measure of one row, four pixels at a time, as the scalar loop below computes
// it; returns where the scalar loop takes over (the last few pixels).
int ridge_row_sse2(const float* up, const float* row, const float* dn, float* out, float* out_nx, float* out_ny,
                   float* out_offset, int x, int x_end, float s2_, float inv_sigma_) {
  const __m128 two = _mm_set1_ps(2.0f), half = _mm_set1_ps(0.5f), quarter = _mm_set1_ps(0.25f), four = _mm_set1_ps(4.0f);
  const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f), minus_one = _mm_set1_ps(-1.0f);
  const __m128 sign = _mm_set1_ps(-0.0f), tiny = _mm_set1_ps(1e-30f);
  const __m128 s2 = _mm_set1_ps(s2_), inv_sigma = _mm_set1_ps(inv_sigma_);
  for (; x + 4 <= x_end; x += 4) {
    const __m128 r_l = _mm_loadu_ps(row + x - 1), r_c = _mm_loadu_ps(row + x), r_r = _mm_loadu_ps(row + x + 1);
    const __m128 u_l = _mm_loadu_ps(up + x - 1), u_c = _mm_loadu_ps(up + x), u_r = _mm_loadu_ps(up + x + 1);
    const __m128 d_l = _mm_loadu_ps(dn + x - 1), d_c = _mm_loadu_ps(dn + x), d_r = _mm_loadu_ps(dn + x + 1);
    const __m128 a = _mm_add_ps(_mm_sub_ps(r_r, _mm_mul_ps(two, r_c)), r_l);
    const __m128 c = _mm_add_ps(_mm_sub_ps(d_c, _mm_mul_ps(two, r_c)), u_c);
    const __m128 b = _mm_mul_ps(quarter, _mm_add_ps(_mm_sub_ps(_mm_sub_ps(d_r, d_l), u_r), u_l));
    const __m128 amc = _mm_sub_ps(a, c);
    const __m128 root = _mm_sqrt_ps(_mm_add_ps(_mm_mul_ps(amc, amc), _mm_mul_ps(four, _mm_mul_ps(b, b))));
    const __m128 apc = _mm_add_ps(a, c);
    const __m128 l2 = _mm_mul_ps(half, _mm_sub_ps(apc, root));
    const __m128 l1 = _mm_mul_ps(half, _mm_add_ps(apc, root));
    const __m128 old = _mm_loadu_ps(out + x);
    const __m128 ridge = _mm_cmplt_ps(l2, zero);
    const __m128 strength = _mm_mul_ps(s2, _mm_sub_ps(zero, l2));
    // Damping factors are at most 1: lanes that cannot win are skipped when all four are.
    if (_mm_movemask_ps(_mm_and_ps(ridge, _mm_cmpgt_ps(strength, old))) == 0) continue;
    const __m128 l2a = _mm_sub_ps(l2, a), l2c = _mm_sub_ps(l2, c);
    const __m128 second = _mm_cmpgt_ps(_mm_andnot_ps(sign, l2c), _mm_andnot_ps(sign, l2a));
    __m128 nx = select_ps(second, l2c, b), ny = select_ps(second, b, l2a);
    const __m128 nn2 = _mm_add_ps(_mm_mul_ps(nx, nx), _mm_mul_ps(ny, ny));
    const __m128 has = _mm_cmpgt_ps(nn2, zero);
    const __m128 inv = _mm_div_ps(one, _mm_sqrt_ps(_mm_max_ps(nn2, tiny)));
    nx = select_ps(has, _mm_mul_ps(nx, inv), one);
    ny = select_ps(has, _mm_mul_ps(ny, inv), zero);
    const __m128 gx = _mm_mul_ps(half, _mm_sub_ps(r_r, r_l)), gy = _mm_mul_ps(half, _mm_sub_ps(d_c, u_c));
    const __m128 l2s = select_ps(ridge, l2, minus_one);
    const __m128 offset = _mm_div_ps(_mm_sub_ps(zero, _mm_add_ps(_mm_mul_ps(gx, nx), _mm_mul_ps(gy, ny))), l2s);
    const __m128 blob = _mm_div_ps(l1, l2s);
    const __m128 edge = _mm_mul_ps(offset, inv_sigma);
    const __m128 arg = _mm_sub_ps(_mm_mul_ps(_mm_set1_ps(-2.0f), _mm_mul_ps(blob, blob)),
                                  _mm_mul_ps(_mm_set1_ps(3.125f), _mm_mul_ps(edge, edge)));
    const __m128 response = _mm_and_ps(ridge, _mm_mul_ps(strength, exp_negative_ps(arg)));
    const __m128 better = _mm_cmpgt_ps(response, old);
    _mm_storeu_ps(out + x, select_ps(better, response, old));
    _mm_storeu_ps(out_nx + x, select_ps(better, nx, _mm_loadu_ps(out_nx + x)));
    _mm_storeu_ps(out_ny + x, select_ps(better, ny, _mm_loadu_ps(out_ny + x)));
    const __m128 clamped = _mm_min_ps(_mm_max_ps(offset, minus_one), one);
    _mm_storeu_ps(out_offset + x, select_ps(better, clamped, _mm_loadu_ps(out_offset + x)));
  }
  return x;
}
#endif

std::vector<double> scales_of(const SegmentationOptions& o) {
  if (!o.scales_px.empty()) return o.scales_px;
  std::vector<double> s;
  for (const double f : {0.35, 0.5, 0.7}) s.push_back(std::max(0.8, f * o.device_width_px));
  return s;
}

Ridge compute_ridge(const cv::Mat& intensity, const cv::Rect& inner, const SegmentationOptions& o) {
  cv::Mat p;
  cv::log(intensity + 1.0f, p);
  p = -p;
  Ridge r;
  cv::GaussianBlur(p, r.attenuation, cv::Size(0, 0), 1.0);
  // White top-hat: p minus its opening by a square wider than any device, which removes the
  // background and every structure wider than a device (vertebral bodies, pelvis, soft
  // tissue, step edges) and keeps thin curves at their full contrast.
  {
    const int d = std::max(5, 2 * static_cast<int>(std::round(1.25 * o.device_width_px)) + 1);
    cv::Mat opened;
    // A square (separable, so fast): it fits into no curve narrower than d in either
    // direction, whatever the curve's orientation, and into every structure wider than √2·d.
    cv::morphologyEx(p, opened, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(d, d)));
    p -= opened;
  }
  r.contrast = p;
  const int H = p.rows, W = p.cols;
  cv::Mat raw(H, W, CV_32F, cv::Scalar(0.0f));
  r.nx = cv::Mat(H, W, CV_32F, cv::Scalar(1.0f));
  r.ny = cv::Mat(H, W, CV_32F, cv::Scalar(0.0f));
  r.offset = cv::Mat(H, W, CV_32F, cv::Scalar(0.0f));
  cv::Mat g;
  for (const double sigma : scales_of(o)) {
    cv::GaussianBlur(p, g, cv::Size(0, 0), sigma, sigma, cv::BORDER_REFLECT);
    const float s2 = static_cast<float>(sigma * sigma);
    const float inv_sigma = static_cast<float>(1.0 / sigma);
    // Rows are independent (each pixel keeps its own best scale, the scales in order), so
    // they are split over OpenCV's threads.
    const int y_begin = std::max(inner.y, 1), y_end = std::min(inner.y + inner.height, H - 1);
    cv::parallel_for_(cv::Range(y_begin, std::max(y_begin, y_end)), [&](const cv::Range& rows) {
      for (int y = rows.start; y < rows.end; ++y) {
        const float* up = g.ptr<float>(y - 1);
        const float* row = g.ptr<float>(y);
        const float* dn = g.ptr<float>(y + 1);
        float* out = raw.ptr<float>(y);
        float* out_nx = r.nx.ptr<float>(y);
        float* out_ny = r.ny.ptr<float>(y);
        float* out_offset = r.offset.ptr<float>(y);
        const int x_end = std::min(inner.x + inner.width, W - 1);
        int x = std::max(inner.x, 1);
#if defined(__SSE2__)
        x = ridge_row_sse2(up, row, dn, out, out_nx, out_ny, out_offset, x, x_end, s2, inv_sigma);
#endif
        for (; x < x_end; ++x) {
          const float a = row[x + 1] - 2.0f * row[x] + row[x - 1];
          const float c = dn[x] - 2.0f * row[x] + up[x];
          const float b = 0.25f * (dn[x + 1] - dn[x - 1] - up[x + 1] + up[x - 1]);
          const float root = std::sqrt((a - c) * (a - c) + 4.0f * b * b);
          const float l2 = 0.5f * (a + c - root);  // across the ridge (most negative)
          // The damping factors below are at most 1: a pixel this scale cannot win is skipped.
          if (!(l2 < 0.0f) || !(s2 * (-l2) > out[x])) continue;
          const float l1 = 0.5f * (a + c + root);
          // Eigenvector of l2: the better conditioned of (b, l2 − a) and (l2 − c, b).
          float nx = b, ny = l2 - a;
          if (std::abs(l2 - c) > std::abs(ny)) nx = l2 - c, ny = b;
          const float nn = std::sqrt(nx * nx + ny * ny);
          if (!(nn > 0.0f)) nx = 1.0f, ny = 0.0f;
          else nx /= nn, ny /= nn;
          const float gx = 0.5f * (row[x + 1] - row[x - 1]), gy = 0.5f * (dn[x] - up[x]);
          const float offset = -(gx * nx + gy * ny) / l2;
          const float blob = l1 / l2;
          const float edge = offset * inv_sigma;
          // β = 0.5 for blobs; 0.4 σ for the offset: a ridge pixel is within half a pixel of
          // the centre, the flank of a blurred step edge about σ from it.
          const float response = s2 * (-l2) * std::exp(-2.0f * blob * blob - 3.125f * edge * edge);
          if (response > out[x]) {
            out[x] = response;
            out_nx[x] = nx;
            out_ny[x] = ny;
            out_offset[x] = std::clamp(offset, -1.0f, 1.0f);
          }
        }
      }
    });
  }
  // Local noise level: per 64-pixel block, the 90th percentile of the positive responses
  // (almost all of a block is background; the measure's noise has a long tail, so the
  // median would put every tenth background pixel above six units), interpolated between
  // blocks.
  constexpr int kBlock = 64;
  const int bx = std::max(1, (inner.width + kBlock - 1) / kBlock), by = std::max(1, (inner.height + kBlock - 1) / kBlock);
  cv::Mat noise(by, bx, CV_32F, cv::Scalar(0.0f));
  std::vector<float> values;
  float global = 0.0f;
  {
    std::vector<float> all;
    for (int y = inner.y; y < inner.y + inner.height; y += 3)
      for (int x = inner.x; x < inner.x + inner.width; x += 3)
        if (const float v = raw.at<float>(y, x); v > 0.0f) all.push_back(v);
    if (!all.empty()) {
      const auto q = static_cast<long>(0.9 * static_cast<double>(all.size()));
      std::nth_element(all.begin(), all.begin() + q, all.end());
      global = all[static_cast<std::size_t>(q)];
    }
  }
  for (int j = 0; j < by; ++j)
    for (int i = 0; i < bx; ++i) {
      values.clear();
      for (int y = inner.y + j * kBlock; y < std::min(inner.y + (j + 1) * kBlock, inner.y + inner.height); ++y)
        for (int x = inner.x + i * kBlock; x < std::min(inner.x + (i + 1) * kBlock, inner.x + inner.width); ++x)
          if (const float v = raw.at<float>(y, x); v > 0.0f) values.push_back(v);
      float level = global;
      if (values.size() > 200) {
        const auto q = static_cast<long>(0.9 * static_cast<double>(values.size()));
        std::nth_element(values.begin(), values.begin() + q, values.end());
        level = values[static_cast<std::size_t>(q)];
      }
      noise.at<float>(j, i) = std::max(level, 1e-12f);
    }
  cv::Mat noise_full;
  cv::resize(noise, noise_full, inner.size(), 0, 0, cv::INTER_LINEAR);
  r.response = cv::Mat(H, W, CV_32F, cv::Scalar(0.0f));
  if (global > 0.0f) r.response(inner) = raw(inner) / noise_full;
  return r;
}

float bilinear(const cv::Mat& m, float x, float y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= m.cols || y0 + 1 >= m.rows) return 0.0f;
  const float fx = x - static_cast<float>(x0), fy = y - static_cast<float>(y0);
  return (1 - fy) * ((1 - fx) * m.at<float>(y0, x0) + fx * m.at<float>(y0, x0 + 1)) +
         fy * ((1 - fx) * m.at<float>(y0 + 1, x0) + fx * m.at<float>(y0 + 1, x0 + 1));
}

std::vector<Eigen::Vector2d> resample_and_smooth(const std::vector<Eigen::Vector2d>& pts, double step, double sigma) {
  if (pts.size() < 2) return pts;
  const std::vector<Eigen::Vector2d> even = resample_2d(pts, step);
  const int n = static_cast<int>(even.size());
  if (n < 2) return even;
  const double length = [&] {
    double l = 0.0;
    for (std::size_t i = 1; i < even.size(); ++i) l += (even[i] - even[i - 1]).norm();
    return l;
  }();
  // Gaussian along arc length; the window shrinks symmetrically at the ends, so the tip and
  // the border point are not pulled inwards.
  const double sig = sigma / (length / (n - 1));
  if (!(sig > 0.0)) return even;
  const int half = static_cast<int>(std::ceil(3.0 * sig));
  std::vector<Eigen::Vector2d> out(even.size());
  for (int i = 0; i < n; ++i) {
    const int h = std::min({half, i, n - 1 - i});
    Eigen::Vector2d acc = Eigen::Vector2d::Zero();
    double wsum = 0.0;
    for (int j = -h; j <= h; ++j) {
      const double w = std::exp(-0.5 * j * j / (sig * sig));
      acc += w * even[static_cast<std::size_t>(i + j)];
      wsum += w;
    }
    out[static_cast<std::size_t>(i)] = acc / wsum;
  }
  return out;
}

}  // namespace

namespace {

// The whole search on one grid (the frame, or the frame at half resolution).
// `k`: the grid's pixel in frame pixels (messages speak in frame pixels).
DeviceCurve2D segment_on_grid(const cv::Mat& f, const cv::Rect& field, const SegmentationOptions& o, int k = 1) {
  DeviceCurve2D result;
  const int H = f.rows, W = f.cols;
  result.field = field;
  if (result.field.area() == 0) {
    result.reason = "the image has no exposed field (no row or column is brighter than the shutters)";
    return result;
  }
  // Drop the field's rim: the shutter edge itself is the strongest structure there.
  const auto scales = scales_of(o);
  const int rim = static_cast<int>(std::ceil(2.0 * *std::max_element(scales.begin(), scales.end()) + o.device_width_px)) + 2;
  cv::Rect inner(result.field.x + rim, result.field.y + rim, result.field.width - 2 * rim, result.field.height - 2 * rim);
  if (inner.width < 8 || inner.height < 8) {
    result.reason = "the exposed field is too small to search";
    return result;
  }
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  const Ridge ridge = compute_ridge(f, inner, o);
  const cv::Mat& R = ridge.response;
  const auto t1 = Clock::now();
  result.ridge_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  struct PathTimer {
    DeviceCurve2D& r;
    Clock::time_point t;
    ~PathTimer() { r.path_ms = std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }
  } path_timer{result, t1};

  // Non-maximum suppression across the ridge, then hysteresis.
  cv::Mat ridge_px(H, W, CV_8U, cv::Scalar(0));
  for (int y = inner.y; y < inner.y + inner.height; ++y)
    for (int x = inner.x; x < inner.x + inner.width; ++x) {
      const float v = R.at<float>(y, x);
      if (v < o.low_threshold) continue;
      const float nx = ridge.nx.at<float>(y, x), ny = ridge.ny.at<float>(y, x);
      if (v >= bilinear(R, x + nx, y + ny) && v >= bilinear(R, x - nx, y - ny)) ridge_px.at<std::uint8_t>(y, x) = 1;
    }
  cv::Mat confident(H, W, CV_8U, cv::Scalar(0));
  {
    std::vector<int> stack, component;
    cv::Mat seen(H, W, CV_8U, cv::Scalar(0));
    for (int y = inner.y; y < inner.y + inner.height; ++y)
      for (int x = inner.x; x < inner.x + inner.width; ++x) {
        if (!ridge_px.at<std::uint8_t>(y, x) || seen.at<std::uint8_t>(y, x) || R.at<float>(y, x) < o.high_threshold) continue;
        component.clear();
        stack.assign(1, y * W + x);
        seen.at<std::uint8_t>(y, x) = 1;
        while (!stack.empty()) {
          const int q = stack.back();
          stack.pop_back();
          component.push_back(q);
          const int qy = q / W, qx = q % W;
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int ny = qy + dy, nx = qx + dx;
              if (ny < 0 || nx < 0 || ny >= H || nx >= W || seen.at<std::uint8_t>(ny, nx) || !ridge_px.at<std::uint8_t>(ny, nx))
                continue;
              seen.at<std::uint8_t>(ny, nx) = 1;
              stack.push_back(ny * W + nx);
            }
        }
        if (component.size() >= 12)  // chains of noise maxima are shorter
          for (const int q : component) confident.at<std::uint8_t>(q / W, q % W) = 1;
      }
  }
  if (cv::countNonZero(confident) == 0) {
    result.reason = "no ridge stronger than " + std::to_string(o.high_threshold) + " noise units";
    return result;
  }

  // Band around the confident pixels, and the minimal path from the field border.
  cv::Mat dist_to_confident;
  cv::Mat not_confident = confident == 0;
  cv::distanceTransform(not_confident, dist_to_confident, cv::DIST_L2, 3);

  // 1 on a confident ridge, 31 on flat background: crossing 10 px of background costs as
  // much as following 300 px of wire.
  // Within the confident band the cost still falls towards the ridge centre, so the path
  // keeps to it instead of wandering across the wire's width.
  const auto cost = [&](int y, int x) {
    const float r = R.at<float>(y, x) / static_cast<float>(o.high_threshold);
    const float miss = 1.0f - std::min(r, 1.0f);
    return 1.0f + 30.0f * miss * miss + 0.5f * (1.0f - std::min(r / 8.0f, 1.0f));
  };
  // The band (pixels of the inner field within the gap radius of a confident one) and the
  // cost of each of its pixels, once: the search below reads every pixel from each of its
  // eight neighbours. Outside the band the cost is never read. The band stays a rim inside
  // the image, so a band pixel's neighbours are all in the image.
  std::vector<std::uint8_t> band(static_cast<std::size_t>(H) * static_cast<std::size_t>(W), 0);
  std::vector<float> band_cost(band.size(), 0.0f);
  for (int y = inner.y; y < inner.y + inner.height; ++y)
    for (int x = inner.x; x < inner.x + inner.width; ++x)
      if (dist_to_confident.at<float>(y, x) <= o.gap_radius_px) {
        const auto q = static_cast<std::size_t>(y) * static_cast<std::size_t>(W) + static_cast<std::size_t>(x);
        band[q] = 1;
        band_cost[q] = cost(y, x);
      }
  std::vector<float> dist(static_cast<std::size_t>(H) * static_cast<std::size_t>(W), kInf);
  std::vector<int> parent(dist.size(), -1);
  std::vector<int> order;  // settled pixels, parents before children
  // (distance, pixel) packed into one word that orders as the pair does (the bits of a
  // non-negative float order as the float): one integer compare per heap step.
  std::priority_queue<std::uint64_t, std::vector<std::uint64_t>, std::greater<>> heap;
  const auto push = [&heap](float d, int q) {
    heap.push(static_cast<std::uint64_t>(std::bit_cast<std::uint32_t>(d)) << 32 | static_cast<std::uint32_t>(q));
  };
  for (int y = inner.y; y < inner.y + inner.height; ++y)
    for (int x = inner.x; x < inner.x + inner.width; ++x) {
      const bool on_border = x == inner.x || y == inner.y || x == inner.x + inner.width - 1 || y == inner.y + inner.height - 1;
      if (on_border && band[static_cast<std::size_t>(y * W + x)]) {
        dist[static_cast<std::size_t>(y * W + x)] = 0.0f;
        push(0.0f, y * W + x);
      }
    }
  const bool border_reachable = !heap.empty();
  if (!border_reachable) {
    // The device lies wholly inside the field: start from its strongest pixel instead and
    // take the farthest confident pixel as the far end.
    cv::Point best;
    cv::Mat masked;
    R.copyTo(masked, confident);
    cv::minMaxLoc(masked, nullptr, nullptr, nullptr, &best);
    if (!band[static_cast<std::size_t>(best.y * W + best.x)]) {  // no confident pixel has a response
      result.reason = "no ridge stronger than " + std::to_string(o.high_threshold) + " noise units";
      return result;
    }
    dist[static_cast<std::size_t>(best.y * W + best.x)] = 0.0f;
    push(0.0f, best.y * W + best.x);
  }
  const auto run_dijkstra = [&] {
    order.clear();
    while (!heap.empty()) {
      const std::uint64_t top = heap.top();
      heap.pop();
      const float d = std::bit_cast<float>(static_cast<std::uint32_t>(top >> 32));
      const int q = static_cast<int>(static_cast<std::uint32_t>(top));
      if (d > dist[static_cast<std::size_t>(q)]) continue;
      order.push_back(q);
      const int qy = q / W, qx = q % W;
      const float cq = band_cost[static_cast<std::size_t>(q)];
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          if (!dx && !dy) continue;
          const int ny = qy + dy, nx = qx + dx;
          const auto idx = static_cast<std::size_t>(ny * W + nx);
          if (!band[idx]) continue;
          const float step = (dx && dy) ? 1.41421356f : 1.0f;
          const float nd = d + step * 0.5f * (cq + band_cost[idx]);
          if (nd < dist[idx]) {
            dist[idx] = nd;
            parent[idx] = q;
            push(nd, ny * W + nx);
          }
        }
    }
  };
  run_dijkstra();
  // The search again from one pixel only.
  const auto reroot = [&](int root) {
    std::fill(dist.begin(), dist.end(), kInf);
    std::fill(parent.begin(), parent.end(), -1);
    dist[static_cast<std::size_t>(root)] = 0.0f;
    push(0.0f, root);
    run_dijkstra();
  };
  if (!border_reachable) {
    // Re-root at the far end of the device so the path runs end to end.
    int far = order.front();
    for (const int q : order)
      if (confident.at<std::uint8_t>(q / W, q % W) && dist[static_cast<std::size_t>(q)] > dist[static_cast<std::size_t>(far)]) far = q;
    reroot(far);
  }

  // Evidence collected on the way to the root: +1 per pixel on (or next to) a confident
  // ridge, −1.5 per other pixel, and −5 per pixel where the path turns by more than 50°
  // over 8 px (a wire bends gently; stepping from a bony rim onto it makes a corner).
  // Only confident pixels that look like a line on the background count: the background
  // 1.5 device widths to either side must differ by less than 0.3 of the line's contrast
  // (the rim of a bone sits on a step, a wire does not).
  cv::Mat contrast_local;
  const int reach = std::max(3, 2 * static_cast<int>(std::round(0.5 * o.device_width_px)) + 1);
  cv::dilate(ridge.contrast, contrast_local, cv::Mat::ones(reach, reach, CV_8U));
  const float side = static_cast<float>(1.5 * o.device_width_px);
  const auto side_step_at = [&](int y, int x) {
    const float nx = ridge.nx.at<float>(y, x), ny = ridge.ny.at<float>(y, x), off = ridge.offset.at<float>(y, x);
    const float cx = x + off * nx, cy = y + off * ny;
    return std::abs(bilinear(ridge.attenuation, cx + side * nx, cy + side * ny) -
                    bilinear(ridge.attenuation, cx - side * nx, cy - side * ny));
  };
  cv::Mat line_like(H, W, CV_8U, cv::Scalar(0));
  for (int y = inner.y; y < inner.y + inner.height; ++y)
    for (int x = inner.x; x < inner.x + inner.width; ++x)
      if (confident.at<std::uint8_t>(y, x) && side_step_at(y, x) <= 0.3f * contrast_local.at<float>(y, x))
        line_like.at<std::uint8_t>(y, x) = 1;
  cv::Mat near_confident;
  cv::dilate(line_like, near_confident, cv::Mat::ones(3, 3, CV_8U));
  const auto ancestor = [&](int q, int k) {
    for (; k > 0 && q >= 0; --k) q = parent[static_cast<std::size_t>(q)];
    return q;
  };
  // A device has the same contrast all along (the attenuation image makes it independent
  // of the background), so a pixel counts as ridge only if its response is at least 35 %
  // of the running mean along the path so far: a faint bony line met by the path is gap.
  // The strength of the ridge a path pixel is on: the largest response within the
  // device's width (the path may run a pixel off the centre).
  cv::Mat R_local;
  cv::dilate(R, R_local, cv::Mat::ones(reach, reach, CV_8U));
  std::vector<float> score(dist.size(), -kInf);
  std::vector<float> running(dist.size(), 0.0f);
  std::vector<float> running_contrast(dist.size(), 0.0f);
  const auto choose_tip = [&] {
    for (const int q : order) {
      const int y = q / W, x = q % W;
      const int p = parent[static_cast<std::size_t>(q)];
      const float r = R_local.at<float>(y, x);
      const float c = contrast_local.at<float>(y, x);
      const float mean_so_far = p < 0 ? 0.0f : running[static_cast<std::size_t>(p)];
      const float contrast_so_far = p < 0 ? 0.0f : running_contrast[static_cast<std::size_t>(p)];
      // The contrast (Δp) too: noise is stronger over bone (fewer quanta), and a chain of
      // noise maxima there can pass on noise units but never has a device's Δp.
      const bool ridge = near_confident.at<std::uint8_t>(y, x) && r >= 0.35f * mean_so_far && c >= 0.5f * contrast_so_far;
      // Only pixels that pass update the means, so a long faint line cannot drag them down.
      running[static_cast<std::size_t>(q)] =
          !ridge ? mean_so_far : (mean_so_far == 0.0f ? r : mean_so_far + (r - mean_so_far) / 30.0f);
      running_contrast[static_cast<std::size_t>(q)] =
          !ridge ? contrast_so_far : (contrast_so_far == 0.0f ? c : contrast_so_far + (c - contrast_so_far) / 30.0f);
      float gain = ridge ? 1.0f : -1.5f;
      if (const int a = ancestor(q, 8); a >= 0)
        if (const int b = ancestor(a, 8); b >= 0) {
          const Eigen::Vector2f v1(x - a % W, y - a / W), v2(a % W - b % W, a / W - b / W);
          if (v1.dot(v2) < std::cos(50.0f * 3.14159265f / 180.0f) * v1.norm() * v2.norm()) gain -= 5.0f;
        }
      score[static_cast<std::size_t>(q)] = (p < 0 ? 0.0f : score[static_cast<std::size_t>(p)]) + gain;
    }
    int tip = -1;
    for (const int q : order) {
      const int y = q / W, x = q % W;
      if (!line_like.at<std::uint8_t>(y, x)) continue;
      if (o.seed_px && (Eigen::Vector2d(x, y) - *o.seed_px).norm() > o.seed_radius_px) continue;
      if (tip < 0 || score[static_cast<std::size_t>(q)] > score[static_cast<std::size_t>(tip)]) tip = q;
    }
    return tip;
  };
  int tip = choose_tip();
  if (tip >= 0 && border_reachable) {
    // Every pixel's path runs to its nearest border, so a device that crosses the whole
    // field (both ends outside it) splits where the two ways out cost the same, and the
    // tip found is that middle. Rooted at the border end of the path found, the same
    // choice sees the device's whole visible length.
    int root = tip;
    while (parent[static_cast<std::size_t>(root)] >= 0) root = parent[static_cast<std::size_t>(root)];
    reroot(root);
    tip = choose_tip();  // rewrites every score it reads: parents come first in `order`
  }
  if (tip < 0) {
    result.reason = o.seed_px ? "nothing device-like within " + std::to_string(static_cast<int>(k * o.seed_radius_px)) + " px of the seed"
                              : "no confident ridge connects to the field";
    return result;
  }

  // The path, tip first; a trailing stretch that is mostly gap is not the device.
  std::vector<int> path;
  for (int q = tip; q >= 0; q = parent[static_cast<std::size_t>(q)]) path.push_back(q);
  // Judged again against the device's own contrast, now that the path is known (the
  // running means start at the border, which may be past the device's end).
  float device_response = 0.0f, device_contrast = 0.0f;
  {
    std::vector<float> rs, cs;
    for (const int q : path)
      if (near_confident.at<std::uint8_t>(q / W, q % W)) {
        rs.push_back(R_local.at<float>(q / W, q % W));
        cs.push_back(contrast_local.at<float>(q / W, q % W));
      }
    if (!rs.empty()) {
      std::nth_element(rs.begin(), rs.begin() + static_cast<long>(rs.size() / 2), rs.end());
      std::nth_element(cs.begin(), cs.begin() + static_cast<long>(cs.size() / 2), cs.end());
      device_response = rs[rs.size() / 2];
      device_contrast = cs[cs.size() / 2];
    }
  }
  const auto ridge_at = [&](int q) {
    const int y = q / W, x = q % W;
    return near_confident.at<std::uint8_t>(y, x) && R_local.at<float>(y, x) >= 0.35f * device_response &&
           contrast_local.at<float>(y, x) >= 0.5f * device_contrast;
  };
  // Keep the prefix (from the tip) with the most evidence: past the device's proximal end
  // the path to the border is gap with a few stray ridge pixels.
  std::size_t best_end = 0;
  float running_score = 0.0f, best_score = -kInf;
  for (std::size_t i = 0; i < path.size(); ++i) {
    running_score += ridge_at(path[i]) ? 1.0f : -1.5f;
    if (running_score >= best_score) best_score = running_score, best_end = i;
  }
  result.reaches_border = border_reachable && path.size() - 1 - best_end <= static_cast<std::size_t>(o.device_width_px) + 2;
  path.resize(best_end + 1);
  std::vector<float> contrasts, steps;
  std::vector<Eigen::Vector2d> centres;
  std::vector<float> along;
  int gaps = 0;
  for (const int q : path) {
    const int y = q / W, x = q % W;
    const float off = ridge.offset.at<float>(y, x);
    centres.emplace_back(x + off * ridge.nx.at<float>(y, x), y + off * ridge.ny.at<float>(y, x));
    along.push_back(R.at<float>(y, x));
    if (ridge_at(q)) {
      contrasts.push_back(contrast_local.at<float>(y, x));
      steps.push_back(side_step_at(y, x));
    }
    gaps += ridge_at(q) ? 0 : 1;
  }
  result.points = resample_and_smooth(centres, o.sample_step_px, o.smoothing_px);
  for (std::size_t i = 1; i < result.points.size(); ++i) result.length_px += (result.points[i] - result.points[i - 1]).norm();
  result.gap_fraction = static_cast<double>(gaps) / static_cast<double>(path.size());
  std::nth_element(along.begin(), along.begin() + static_cast<long>(along.size() / 2), along.end());
  result.median_response = along[along.size() / 2];
  result.confidence = (1.0 - result.gap_fraction) * std::min(1.0, result.median_response / o.high_threshold);
  if (!contrasts.empty()) {
    std::nth_element(contrasts.begin(), contrasts.begin() + static_cast<long>(contrasts.size() / 2), contrasts.end());
    result.contrast = contrasts[contrasts.size() / 2];
  }
  if (!steps.empty()) {
    std::nth_element(steps.begin(), steps.begin() + static_cast<long>(steps.size() / 2), steps.end());
    result.side_step = steps[steps.size() / 2];
  }
  // A device is a line on the background: the same background on both sides. The border
  // of a bone or of the body is a step with a rim on it.
  if (result.side_step > 0.3 * result.contrast) {
    result.reason = "the strongest curve is the edge of a wider structure (one side is " +
                    std::to_string(result.side_step) + " −log units denser than the other, the curve itself " +
                    std::to_string(result.contrast) + "): no device in the image";
    result.points.clear();
    return result;
  }
  if (result.contrast < o.min_contrast) {
    result.reason = "the strongest curve has a contrast of " + std::to_string(result.contrast) +
                    " (attenuation, −log units), below the " + std::to_string(o.min_contrast) +
                    " of a device: no device in the image";
    result.points.clear();
    return result;
  }
  // The measure is in noise units: on a device most of the path is confident (above the
  // high threshold). A chain of noise maxima strung together by the minimal path has only a
  // few confident pixels and a median below it, and is short: the path bridges at most
  // gap_radius_px between confident pixels, so chance alignments rarely run longer than a
  // few such gaps. A weak curve (low dose) is believed only when it is long.
  const double weak_length_px = 4.0 * o.gap_radius_px;
  if (result.median_response < o.high_threshold &&
      (result.median_response < o.low_threshold || result.length_px < weak_length_px)) {
    result.reason = "the strongest curve is only " + std::to_string(result.median_response).substr(0, 4) +
                    " noise units strong along its length and " + std::to_string(static_cast<int>(k * result.length_px)) +
                    " px long (a device is above " + std::to_string(o.high_threshold).substr(0, 4) + ", or above " +
                    std::to_string(o.low_threshold).substr(0, 4) + " over " +
                    std::to_string(static_cast<int>(k * weak_length_px)) + " px): no device in the image";
    result.points.clear();
    return result;
  }
  if (result.length_px < o.min_length_px) {
    result.reason = "the strongest curve is " + std::to_string(static_cast<int>(k * result.length_px)) +
                    " px long, shorter than " + std::to_string(static_cast<int>(k * o.min_length_px)) + " px";
    result.points.clear();
    return result;
  }
  result.found = true;
  return result;
}

// Centre of the device's attenuation profile across the curve at each point, on the full
// grid (the search ran at half resolution): the profile −log(I + 1) over ±0.75 device
// widths along the normal, less the straight line through its two ends (the local
// background), and its centroid. Twice, as the first move changes the window.
void refine_on_full_grid(const cv::Mat& f, const SegmentationOptions& o, std::vector<Eigen::Vector2d>& points) {
  const double reach = 0.75 * o.device_width_px + 1.0;
  const int samples = 2 * static_cast<int>(std::ceil(reach / 0.25)) + 1;
  std::vector<double> s(static_cast<std::size_t>(samples)), c(static_cast<std::size_t>(samples));
  for (int k = 0; k < samples; ++k) s[static_cast<std::size_t>(k)] = -reach + 2.0 * reach * k / (samples - 1);
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<Eigen::Vector2d> moved = points;
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector2d t = points[std::min(i + 1, points.size() - 1)] - points[i > 0 ? i - 1 : 0];
      if (!(t.norm() > 0.0)) continue;
      const Eigen::Vector2d n(-t.y() / t.norm(), t.x() / t.norm());
      for (int k = 0; k < samples; ++k) {
        const Eigen::Vector2d q = points[i] + s[static_cast<std::size_t>(k)] * n;
        c[static_cast<std::size_t>(k)] = -std::log(bilinear(f, static_cast<float>(q.x()), static_cast<float>(q.y())) + 1.0);
      }
      const double left = (c[0] + c[1] + c[2]) / 3.0, right = (c[c.size() - 1] + c[c.size() - 2] + c[c.size() - 3]) / 3.0;
      double sum = 0.0, weighted = 0.0;
      for (int k = 0; k < samples; ++k) {
        const double u = static_cast<double>(k) / (samples - 1);
        const double above = c[static_cast<std::size_t>(k)] - (left + u * (right - left));
        if (above <= 0.0) continue;
        sum += above;
        weighted += s[static_cast<std::size_t>(k)] * above;
      }
      if (sum > 0.0) moved[i] = points[i] + std::clamp(weighted / sum, -1.0, 1.0) * n;
    }
    points = std::move(moved);
  }
}

}  // namespace

DeviceCurve2D segment_device(const cv::Mat& image, const SegmentationOptions& o) {
  cv::Mat f = to_float(image);
  if (!(o.device_width_px > 0.5 && o.device_width_px < 100.0))
    throw std::invalid_argument("segment_device: device width must be 0.5 to 100 px");
  for (const double sc : o.scales_px)
    if (!(sc > 0.0 && sc < 100.0)) throw std::invalid_argument("segment_device: ridge scales must be 0 to 100 px");
  // The path search starts only inside the band these span; a zero or negative threshold
  // would make every pixel confident, and a negative gap radius an empty band.
  if (!(o.high_threshold > 0.0 && o.low_threshold > 0.0 && o.low_threshold <= o.high_threshold &&
        std::isfinite(o.high_threshold)))
    throw std::invalid_argument("segment_device: thresholds must be positive, low at most high");
  if (!(o.gap_radius_px >= 0.0 && std::isfinite(o.gap_radius_px)))
    throw std::invalid_argument("segment_device: the gap radius must be a finite length of 0 px or more");
  const cv::Rect field = exposed_field(f);
  // Integer frames are quantised: in −log units a grey level near k is a step of 1/(k+1),
  // as large as a device's contrast below about 8. A processed video's window clips its
  // dark anatomy to black there, and the clipped region's ragged edge then outshone the
  // wire (20 % of it found on an 8-bit display with clipped blacks, 98 % with this floor).
  // Nothing is seen through such shadows anyway. (After the field: shutters stay dark.)
  if (image.depth() == CV_8U || image.depth() == CV_16U) cv::max(f, kQuantisedFloor, f);
  // Shadows 4 px and wider are searched at half resolution (2 px and wider there: enough
  // for the ridge measure), four times fewer pixels; the result is refined on the frame.
  const int k = o.device_width_px >= 4.0 && f.cols >= 64 && f.rows >= 64 ? 2 : 1;
  if (k == 1) return segment_on_grid(f, field, o);
  cv::Mat half;
  // Even size, so each half-resolution pixel is exactly 2 x 2 frame pixels: x = 2x' + 0.5.
  cv::resize(f(cv::Rect(0, 0, f.cols & ~1, f.rows & ~1)), half, cv::Size(f.cols / 2, f.rows / 2), 0, 0, cv::INTER_AREA);
  SegmentationOptions h = o;
  h.device_width_px /= k;
  for (auto& s : h.scales_px) s = std::max(0.8, s / k);
  h.min_length_px /= k;
  h.gap_radius_px /= k;
  h.sample_step_px /= k;
  h.smoothing_px /= k;
  h.seed_radius_px /= k;
  if (o.seed_px) h.seed_px = (*o.seed_px - Eigen::Vector2d::Constant(0.5)) / k;  // pixel centres: x = 2x' + 0.5
  // Half pixels wholly inside the field (a half pixel straddling a shutter edge is out).
  const int hx0 = (field.x + 1) / k, hy0 = (field.y + 1) / k;
  const int hx1 = (field.x + field.width) / k, hy1 = (field.y + field.height) / k;
  const cv::Rect half_field(hx0, hy0, std::max(0, hx1 - hx0), std::max(0, hy1 - hy0));
  DeviceCurve2D r = segment_on_grid(half, half_field, h, k);
  r.field = field;
  r.length_px *= k;
  if (!r.found) return r;
  for (auto& p : r.points) p = k * p + Eigen::Vector2d::Constant(0.5);
  const auto t0 = std::chrono::steady_clock::now();
  refine_on_full_grid(f, o, r.points);
  r.points = resample_and_smooth(r.points, o.sample_step_px, o.smoothing_px);
  r.length_px = 0.0;
  for (std::size_t i = 1; i < r.points.size(); ++i) r.length_px += (r.points[i] - r.points[i - 1]).norm();
  r.path_ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (r.length_px < o.min_length_px) {  // judged again on the frame
    r.found = false;
    r.reason = "the strongest curve is " + std::to_string(static_cast<int>(r.length_px)) + " px long, shorter than " +
               std::to_string(static_cast<int>(o.min_length_px)) + " px";
    r.points.clear();
  }
  return r;
}

}  // namespace evar::geometry
