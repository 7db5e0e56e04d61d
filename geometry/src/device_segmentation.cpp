#include "evar/geometry/device_segmentation.hpp"

// The search, step by step (device_segmentation_steps.hpp names the file of each): the
// exposed field, the ridge measure, its confident pixels, minimal paths from the field's
// border through the band around them, the tip with the most evidence, and the path
// trimmed, measured and judged; at half resolution for wide shadows, then refined on the
// frame.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "device_segmentation_steps.hpp"

namespace evar::geometry {

namespace {

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

// The whole search on one grid (the frame, or the frame at half resolution).
// `k`: the grid's pixel in frame pixels (messages speak in frame pixels).
DeviceCurve2D segment_on_grid(const cv::Mat& f, const cv::Rect& field, const SegmentationOptions& o, const cv::Mat& field_mask,
                              const cv::Mat& hidden_mask, int k = 1) {
  using namespace segmentation;
  DeviceCurve2D result;
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
  Ridge ridge = compute_ridge(f, inner, o);
  // Inside a field that is not a rectangle only what lies the rim's width inside its edge
  // is searched, as inside the shutters.
  // The field's edge is where a device leaves it; graphics over the field hide what they
  // cover but are no way out of it. Both are kept clear by the rim.
  cv::Mat searched, field_edge;
  if (!field_mask.empty() || !hidden_mask.empty()) {
    const cv::Mat disc = cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * rim + 1, 2 * rim + 1});
    if (!field_mask.empty()) {
      cv::erode(field_mask, field_edge, disc, {-1, -1}, 1, cv::BORDER_CONSTANT, cv::Scalar(0));
      searched = field_edge.clone();
    } else {
      searched = cv::Mat(f.size(), CV_8U, cv::Scalar(255));
    }
    if (!hidden_mask.empty()) {
      cv::Mat hidden;
      cv::dilate(hidden_mask, hidden, disc);
      searched.setTo(0, hidden);
    }
    ridge.response.setTo(0.0f, searched == 0);
  }
  const auto t1 = Clock::now();
  result.ridge_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  struct PathTimer {
    DeviceCurve2D& r;
    Clock::time_point t;
    ~PathTimer() { r.path_ms = std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }
  } path_timer{result, t1};

  const cv::Mat confident = confident_ridge_pixels(ridge, inner, o);
  if (cv::countNonZero(confident) == 0) {
    result.reason = "no ridge stronger than " + std::to_string(o.high_threshold) + " noise units";
    return result;
  }

  RidgePaths paths(ridge, confident, inner, o, searched, field_edge);
  const int W = f.cols;
  const bool border_reachable = paths.seed_border();
  if (border_reachable) {
    paths.run();
  } else {
    // The device lies wholly inside the field: start from its strongest pixel instead and
    // take the farthest confident pixel as the far end.
    cv::Point best;
    cv::Mat masked;
    ridge.response.copyTo(masked, confident);
    cv::minMaxLoc(masked, nullptr, nullptr, nullptr, &best);
    if (!paths.in_band(best.y * W + best.x)) {  // no confident pixel has a response
      result.reason = "no ridge stronger than " + std::to_string(o.high_threshold) + " noise units";
      return result;
    }
    paths.run_from(best.y * W + best.x);
    // Re-root at the far end of the device so the path runs end to end.
    int far = paths.order().front();
    for (const int q : paths.order())
      if (confident.at<std::uint8_t>(q / W, q % W) && paths.distance(q) > paths.distance(far)) far = q;
    paths.reroot(far);
  }

  const PathEvidence evidence = path_evidence(ridge, confident, inner, o);
  TipChooser tips(paths.size());
  int tip = tips.choose(paths, evidence, o);
  if (tip >= 0 && border_reachable) {
    // Every pixel's path runs to its nearest border, so a device that crosses the whole
    // field (both ends outside it) splits where the two ways out cost the same, and the
    // tip found is that middle. Rooted at the border end of the path found, the same
    // choice sees the device's whole visible length.
    int root = tip;
    while (paths.parent(root) >= 0) root = paths.parent(root);
    paths.reroot(root);
    tip = tips.choose(paths, evidence, o);
  }
  if (tip < 0) {
    result.reason = o.seed_px ? "nothing device-like within " + std::to_string(static_cast<int>(k * o.seed_radius_px)) + " px of the seed"
                              : "no confident ridge connects to the field";
    return result;
  }

  // The path, tip first; a trailing stretch that is mostly gap is not the device.
  std::vector<int> path;
  for (int q = tip; q >= 0; q = paths.parent(q)) path.push_back(q);
  measure_and_judge(std::move(path), border_reachable, ridge, evidence, o, k, result);
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
        c[static_cast<std::size_t>(k)] = -std::log(segmentation::bilinear(f, static_cast<float>(q.x()), static_cast<float>(q.y())) + 1.0);
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
  cv::Rect field = exposed_field(f);
  for (const cv::Mat* m : {&o.field_mask, &o.hidden_mask})
    if (!m->empty() && (m->type() != CV_8UC1 || m->size() != f.size()))
      throw std::invalid_argument("segment_device: the field and hidden masks must be 8-bit, of the image's size");
  if (!o.field_mask.empty()) field &= cv::boundingRect(o.field_mask);
  // Integer frames are quantised: in −log units a grey level near k is a step of 1/(k+1),
  // as large as a device's contrast below about 8. A processed video's window clips its
  // dark anatomy to black there, and the clipped region's ragged edge then outshone the
  // wire (20 % of it found on an 8-bit display with clipped blacks, 98 % with this floor).
  // Nothing is seen through such shadows anyway. (After the field: shutters stay dark.)
  if (image.depth() == CV_8U || image.depth() == CV_16U) cv::max(f, kQuantisedFloor, f);
  // Shadows 4 px and wider are searched at half resolution (2 px and wider there: enough
  // for the ridge measure), four times fewer pixels; the result is refined on the frame.
  const int k = o.device_width_px >= 4.0 && f.cols >= 64 && f.rows >= 64 ? 2 : 1;
  if (k == 1) return segment_on_grid(f, field, o, o.field_mask, o.hidden_mask);
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
  // A half pixel is in the field when all four of its frame pixels are, hidden when any is.
  cv::Mat half_field_mask, half_hidden;
  const cv::Rect even(0, 0, f.cols & ~1, f.rows & ~1);
  if (!o.field_mask.empty()) {
    cv::resize(o.field_mask(even), half_field_mask, half.size(), 0, 0, cv::INTER_AREA);
    half_field_mask = half_field_mask == 255;
  }
  if (!o.hidden_mask.empty()) {
    cv::resize(o.hidden_mask(even), half_hidden, half.size(), 0, 0, cv::INTER_AREA);
    half_hidden = half_hidden > 0;
  }
  h.field_mask = h.hidden_mask = cv::Mat();
  DeviceCurve2D r = segment_on_grid(half, half_field, h, half_field_mask, half_hidden, k);
  r.field = field;
  r.length_px *= k;
  if (!r.found) return r;
  for (auto& p : r.points) p = k * p + Eigen::Vector2d::Constant(0.5);
  const auto t0 = std::chrono::steady_clock::now();
  refine_on_full_grid(f, o, r.points);
  r.points = segmentation::resample_and_smooth(r.points, o.sample_step_px, o.smoothing_px);
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
