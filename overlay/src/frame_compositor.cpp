#include "evar/overlay/frame_compositor.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "image_mat.hpp"
#include "roadmap_layer.hpp"

namespace evar::overlay {

namespace {

// Colours (BGR) interventionalists can tell apart on grey fluoroscopy.
constexpr Bgr kInitial{235, 200, 120};   // pale blue: the preoperative roadmap
constexpr Bgr kAdapted{40, 150, 255};    // orange: the adapted roadmap
constexpr Bgr kDevice{80, 255, 120};     // green: the reconstructed device
constexpr Bgr kLandmark{60, 230, 255};   // yellow: ostia
constexpr Bgr kText{245, 245, 245};
constexpr Bgr kAlert{0, 190, 255};       // amber

void check_frame(const GreyFrame& f) {
  if (f.width <= 0 || f.height <= 0)
    throw std::invalid_argument("compose: frame size " + std::to_string(f.width) + " x " + std::to_string(f.height));
  if (f.bits != 8 && f.bits != 16) throw std::invalid_argument("compose: " + std::to_string(f.bits) + "-bit frame (8 or 16)");
  if (f.data == nullptr) throw std::invalid_argument("compose: frame without pixels");
  if (f.stride_bytes < f.width * (f.bits / 8))
    throw std::invalid_argument("compose: stride " + std::to_string(f.stride_bytes) + " bytes is shorter than a row");
}

// Value of pixel (x, y).
inline unsigned value(const GreyFrame& f, int x, int y) {
  const std::uint8_t* row = f.data + static_cast<std::size_t>(y) * static_cast<std::size_t>(f.stride_bytes);
  if (f.bits == 8) return row[x];
  return static_cast<unsigned>(row[2 * x]) | (static_cast<unsigned>(row[2 * x + 1]) << 8);
}

// `text` broken at spaces into lines at most `max_px` wide in this font (a word wider
// than that on its own stays whole: nothing is dropped).
std::vector<std::string> wrapped(const std::string& text, int max_px, double scale, int thickness) {
  std::vector<std::string> out;
  std::string line;
  std::size_t at = 0;
  int baseline = 0;
  while (at < text.size()) {
    const std::size_t space = text.find(' ', at);
    const std::string word = text.substr(at, space == std::string::npos ? std::string::npos : space - at);
    at = space == std::string::npos ? text.size() : space + 1;
    const std::string longer = line.empty() ? word : line + " " + word;
    if (!line.empty() && cv::getTextSize(longer, cv::FONT_HERSHEY_SIMPLEX, scale, thickness, &baseline).width > max_px) {
      out.push_back(line);
      line = "  " + word;  // a continued line is indented
    } else {
      line = longer;
    }
  }
  if (!line.empty() || out.empty()) out.push_back(line);
  return out;
}

// The status block, top left, on a darkened box so it reads on any background; a line
// wider than the frame is wrapped, never cut off.
void draw_status(Image& out, const StatusBlock& status) {
  if (status.lines.empty() && status.alerts.empty()) return;
  cv::Mat canvas = detail::wrap(out);
  const double scale = std::max(0.4, 0.6 * out.height / 1024.0);
  const int thickness = out.height >= 768 ? 2 : 1;
  int baseline = 0;
  const int line_px = cv::getTextSize("Ag", cv::FONT_HERSHEY_SIMPLEX, scale, thickness, &baseline).height + baseline + 6;
  const int max_px = std::max(1, out.width - 16);
  std::vector<std::pair<std::string, Bgr>> rows;
  for (const auto& s : status.lines)
    for (auto& l : wrapped(s, max_px, scale, thickness)) rows.emplace_back(std::move(l), kText);
  for (const auto& s : status.alerts)
    for (auto& l : wrapped(s, max_px, scale, thickness)) rows.emplace_back(std::move(l), kAlert);
  int width = 0;
  for (const auto& [s, c] : rows)
    width = std::max(width, cv::getTextSize(s, cv::FONT_HERSHEY_SIMPLEX, scale, thickness, &baseline).width);
  const cv::Rect box =
      cv::Rect(0, 0, width + 16, static_cast<int>(rows.size()) * line_px + 10) & cv::Rect(0, 0, out.width, out.height);
  cv::Mat roi = canvas(box);
  roi.convertTo(roi, -1, 0.35);  // darken behind the text so it reads on any background
  int y = 4 + line_px - baseline - 3;
  for (const auto& [s, c] : rows) {
    cv::putText(canvas, s, {8, y}, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(c.b, c.g, c.r), thickness, cv::LINE_AA);
    y += line_px;
  }
}

}  // namespace

const char* to_string(RoadmapMode mode) {
  switch (mode) {
    case RoadmapMode::Undeformed: return "undeformed";
    case RoadmapMode::Adapted: return "adapted";
    case RoadmapMode::Both: return "both";
  }
  return "?";
}

std::optional<RoadmapMode> parse_roadmap_mode(std::string_view text) {
  if (text == "undeformed") return RoadmapMode::Undeformed;
  if (text == "adapted") return RoadmapMode::Adapted;
  if (text == "both") return RoadmapMode::Both;
  return std::nullopt;
}

Overlay roadmap_overlay(const RoadmapModel& model, RoadmapMode mode) {
  Overlay o;
  const bool adapted = !model.adapted.empty();
  const bool show_initial = mode != RoadmapMode::Adapted || !adapted;
  const bool show_adapted = mode != RoadmapMode::Undeformed && adapted;
  if (show_initial) {
    // Beside the adapted model the preoperative one is only a reference: fainter, unlabelled.
    const bool reference = show_adapted;
    o.layers.push_back({"preoperative", model.initial, kInitial, reference ? 0.12 : 0.25, true, 1});
    for (const auto& p : model.initial_landmarks)
      o.markers.push_back({p.position_lps, reference ? "" : p.label, "", kLandmark, false, reference ? 4 : 6});
  }
  if (show_adapted) {
    o.layers.push_back({"adapted", model.adapted, kAdapted, 0.25, true, 1});
    for (const auto& p : model.adapted_landmarks)
      o.markers.push_back({p.position_lps, p.label, "", kLandmark, true, 5});
  }
  if (mode != RoadmapMode::Undeformed && model.device.size() >= 2)
    o.polylines.push_back({"", model.device, kDevice, 2});
  return o;
}

FrameCompositor::FrameCompositor(CompositorOptions options) : options_(options) {
  if (options_.supersample < 1 || options_.supersample > 8)
    throw std::invalid_argument("compositor: supersample " + std::to_string(options_.supersample) + " (1 to 8)");
  if (!(options_.window_level.window >= 0.0)) throw std::invalid_argument("compositor: negative window");
  if (options_.layer_in_background) worker_ = std::make_unique<detail::LayerWorker>(options_.supersample);
}

FrameCompositor::~FrameCompositor() = default;

std::size_t FrameCompositor::layer_renders() const { return own_renders_ + (worker_ ? worker_->renders() : 0); }

void FrameCompositor::update_lut(const GreyFrame& f) {
  WindowLevel wl = options_.window_level;
  if (wl.window <= 0.0) {
    // The 1st and 99th percentiles of a sparse grid of pixels: robust to the collimator's
    // black and to burnt-out skin line, cheap enough for every frame.
    const int step = std::max(1, static_cast<int>(std::sqrt(static_cast<double>(f.width) * f.height / 16384.0)));
    samples_.clear();
    for (int y = step / 2; y < f.height; y += step)
      for (int x = step / 2; x < f.width; x += step) samples_.push_back(static_cast<std::uint16_t>(value(f, x, y)));
    const auto at = [&](double q) {
      auto it = samples_.begin() + static_cast<std::ptrdiff_t>(q * static_cast<double>(samples_.size() - 1));
      std::nth_element(samples_.begin(), it, samples_.end());
      return static_cast<double>(*it);
    };
    const double lo = at(0.01), hi = at(0.99);
    wl.window = std::max(hi - lo, 1.0);
    wl.level = 0.5 * (lo + hi);
    // Noise moves the percentiles a little every frame; while neither end of the window
    // moves by a grey level the display is the same, so the table is kept (no flicker, no
    // rebuilding 65536 entries per frame).
    const double grey_level = lut_window_.window / 255.0;
    const double old_low = lut_window_.level - 0.5 * lut_window_.window, old_high = old_low + lut_window_.window;
    if (lut_bits_ == f.bits && std::abs(lo - old_low) < grey_level && std::abs(std::max(hi, lo + 1.0) - old_high) < grey_level)
      wl = lut_window_;
  }
  last_window_ = wl;
  if (lut_bits_ == f.bits && lut_window_.window == wl.window && lut_window_.level == wl.level) return;
  const std::size_t n = std::size_t{1} << f.bits;
  lut_.resize(n);
  const double low = wl.level - 0.5 * wl.window;
  for (std::size_t v = 0; v < n; ++v)
    lut_[v] = static_cast<std::uint8_t>(std::clamp(std::lround(255.0 * (static_cast<double>(v) - low) / wl.window), 0L, 255L));
  lut_bits_ = f.bits;
  lut_window_ = wl;
}

Image FrameCompositor::compose(const GreyFrame& frame, const geometry::ProjectionMatrix* P_ct,
                               const std::shared_ptr<const RoadmapModel>& model, RoadmapMode mode,
                               const StatusBlock& status) {
  check_frame(frame);
  update_lut(frame);
  const detail::RoadmapLayer* shown = nullptr;
  std::string pending;  // a status line while the layer asked for is being drawn
  bool failed = false;  // ...or could not be drawn: then no stand-in either
  last_shown_ = RoadmapShown::None;
  last_layer_error_.clear();
  if (P_ct != nullptr && model != nullptr) {
    const detail::LayerKey key{*P_ct, model.get(), mode, frame.width, frame.height};
    if (worker_) {
      // Two slots: a layer finished for a view the C-arm has already left must not evict
      // the one for the view it came back to. The newest always stays (the worker skips
      // requests it already served).
      if (auto fresh = worker_->take()) {
        if (!fresh->serves(key) && layer_ && layer_->serves(key)) spare_ = std::move(fresh);
        else spare_ = std::exchange(layer_, std::move(fresh));
      }
      if ((!layer_ || !layer_->serves(key)) && spare_ && spare_->serves(key)) std::swap(layer_, spare_);
    }
    if (!layer_ || !layer_->serves(key)) {
      if (!worker_) {
        layer_.reset();  // a throw below leaves no half-made layer behind
        layer_ = std::make_shared<const detail::RoadmapLayer>(detail::draw_roadmap_layer(key, model, options_.supersample));
        ++own_renders_;
      } else {
        worker_->request(key, model);
        last_layer_error_ = worker_->error_for(key);
        failed = !last_layer_error_.empty();
        if (failed) pending = "roadmap not drawn: " + last_layer_error_;
        else if (layer_ && layer_->aligned_with(key)) pending = "roadmap: drawing the new model (previous shown)";
        else pending = "roadmap: drawing for this view";
      }
    }
    if (layer_ && layer_->serves(key)) {
      shown = layer_.get();
      last_shown_ = RoadmapShown::Current;
    } else if (layer_ && !failed && layer_->aligned_with(key)) {
      shown = layer_.get();
      last_shown_ = RoadmapShown::Previous;
    }
  }
  const bool roadmap = shown != nullptr;
  Image out;
  out.width = frame.width;
  out.height = frame.height;
  out.bgr.resize(static_cast<std::size_t>(frame.width) * frame.height * 3);
  const std::uint8_t* lut = lut_.data();
  for (int y = 0; y < frame.height; ++y) {
    std::uint8_t* o = out.bgr.data() + static_cast<std::size_t>(y) * frame.width * 3;
    const std::uint8_t* row = frame.data + static_cast<std::size_t>(y) * frame.stride_bytes;
    if (!roadmap) {
      for (int x = 0; x < frame.width; ++x) {
        const std::uint8_t g = frame.bits == 8 ? lut[row[x]] : lut[row[2 * x] | (row[2 * x + 1] << 8)];
        o[3 * x] = o[3 * x + 1] = o[3 * x + 2] = g;
      }
      continue;
    }
    const std::uint8_t* b = shown->b.data() + static_cast<std::size_t>(y) * frame.width * 3;
    const std::uint8_t* k = shown->k.data() + static_cast<std::size_t>(y) * frame.width * 3;
    for (int x = 0; x < frame.width; ++x) {
      const unsigned g = frame.bits == 8 ? lut[row[x]] : lut[row[2 * x] | (row[2 * x + 1] << 8)];
      for (int c = 0; c < 3; ++c) {
        const unsigned i = 3u * static_cast<unsigned>(x) + static_cast<unsigned>(c);
        o[i] = static_cast<std::uint8_t>(b[i] + (g * k[i] + 127u) / 255u);
      }
    }
  }
  if (pending.empty()) {
    draw_status(out, status);
  } else {
    StatusBlock with_pending = status;
    with_pending.lines.push_back(pending);
    draw_status(out, with_pending);
  }
  return out;
}

}  // namespace evar::overlay
