#include <algorithm>
#include <cmath>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "device_segmentation_steps.hpp"

namespace evar::geometry::segmentation {

namespace {

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

}  // namespace

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

}  // namespace evar::geometry::segmentation
