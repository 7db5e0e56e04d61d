#include "evar/acquisition/geometry_timeline.hpp"

#include <algorithm>
#include <cmath>

namespace evar::acquisition {

namespace {
std::int64_t ns(GeometryTimeline::Clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
}
double lerp(double a, double b, double w) { return a + (b - a) * w; }
// From a to b the short way round (a primary angle of 180° is also −180°).
double turn_deg(double a, double b) { return std::remainder(b - a, 360.0); }
// Into (−180, 180].
double wrap_deg(double a) {
  const double r = std::remainder(a, 360.0);
  return r == -180.0 ? 180.0 : r;
}
}  // namespace

GeometryTimeline::GeometryTimeline(GeometryTimelineOptions options) : options_(options) {}

void GeometryTimeline::add(const CArmState& sample) {
  // Device times come off the wire. Beyond ±2^62 ns (146 years) they are garbage that
  // passed the CRC, and differences with them could overflow.
  constexpr std::int64_t kLimit = std::int64_t{1} << 62;
  if (sample.device_time_ns <= -kLimit || sample.device_time_ns >= kLimit) {
    ++dropped_samples_;
    return;
  }
  if (samples_.empty()) {
    accept(sample);
    return;
  }
  const std::int64_t restart_ns = std::chrono::nanoseconds(options_.restart_after).count();
  const CArmState& newest = samples_.back();
  // A sample cannot arrive before it was taken: by the clock offset so far, how much
  // earlier than its own time it arrived (in double: the sum of two int64 can overflow).
  const double early_ns = static_cast<double>(*clock_.offset_ns()) + static_cast<double>(sample.device_time_ns) -
                          static_cast<double>(ns(sample.host_arrival));
  const bool behind = sample.device_time_ns <= newest.device_time_ns;
  if (behind && newest.device_time_ns - sample.device_time_ns <= restart_ns) {
    ++dropped_samples_;  // late or repeated: interpolation needs increasing times, and the newer samples cover it
    return;
  }
  const bool ahead = !behind && early_ns > static_cast<double>(std::chrono::nanoseconds(options_.ahead_after).count());
  if (!behind && !ahead) {
    if (jump_candidate_) ++dropped_samples_;  // the one held was a stray: the clock went on
    jump_candidate_.reset();
    accept(sample);
    return;
  }
  // Far behind the newest, or far ahead of the C-arm clock as the host sees it: a C-arm
  // clock that restarted or was set, or one stray time (which would spoil the clock offset
  // and, ahead, be served as the newest geometry). The next sample decides: one going on
  // from this one, as far as the host clock went on, confirms the jump.
  if (jump_candidate_ && goes_on(*jump_candidate_, sample)) {
    ++restarts_;
    samples_.clear();
    clock_.reset();
    accept(*jump_candidate_);
    jump_candidate_.reset();
    accept(sample);
    return;
  }
  if (jump_candidate_) ++dropped_samples_;  // the one held before was a stray
  jump_candidate_ = sample;
}

bool GeometryTimeline::goes_on(const CArmState& from, const CArmState& next) const {
  // Device times are within ±2^62 (add), so their difference fits.
  const std::int64_t device_step = next.device_time_ns - from.device_time_ns;
  const std::int64_t host_step = ns(next.host_arrival) - ns(from.host_arrival);
  return device_step > 0 && device_step <= host_step + std::chrono::nanoseconds(options_.restart_after).count();
}

void GeometryTimeline::accept(const CArmState& sample) {
  clock_.add(sample.device_time_ns, ns(sample.host_arrival));
  samples_.push_back(sample);
  const std::int64_t oldest = sample.device_time_ns - std::chrono::nanoseconds(options_.window).count();
  while (samples_.size() > 2 && samples_.front().device_time_ns < oldest) samples_.pop_front();
}

std::optional<FrameGeometry> GeometryTimeline::at(Clock::time_point t) const {
  if (samples_.empty()) return std::nullopt;
  // The frame's time on the C-arm clock, by the newest offset estimate.
  return at_carm_time(ns(t) - *clock_.offset_ns());
}

std::optional<FrameGeometry> GeometryTimeline::at_carm_time(std::int64_t tn) const {
  if (samples_.empty()) return std::nullopt;
  const std::int64_t stale_ns = std::chrono::nanoseconds(options_.stale_after).count();
  auto after = std::lower_bound(samples_.begin(), samples_.end(), tn,
                                [](const CArmState& s, std::int64_t v) { return s.device_time_ns < v; });
  FrameGeometry g;
  if (after == samples_.begin() || after == samples_.end()) {
    // Outside the history: hold the end sample; stale when it is too far away.
    g.state = after == samples_.begin() ? samples_.front() : samples_.back();
    g.age_ns = std::llabs(tn - g.state.device_time_ns);
    g.moving = g.state.moving;
    g.stale = g.age_ns > stale_ns;
    return g;
  }
  const CArmState& b = *after;
  const CArmState& a = *(after - 1);
  const std::int64_t ta = a.device_time_ns, tb = b.device_time_ns;
  const double w = tb > ta ? static_cast<double>(tn - ta) / static_cast<double>(tb - ta) : 0.0;
  g.state = w < 0.5 ? a : b;  // flags and times of the nearer sample
  g.state.primary_deg = wrap_deg(a.primary_deg + w * turn_deg(a.primary_deg, b.primary_deg));
  g.state.secondary_deg = lerp(a.secondary_deg, b.secondary_deg, w);
  g.state.sid_mm = lerp(a.sid_mm, b.sid_mm, w);
  g.state.sod_mm = lerp(a.sod_mm, b.sod_mm, w);
  for (std::size_t k = 0; k < 3; ++k) g.state.table_mm[k] = lerp(a.table_mm[k], b.table_mm[k], w);
  g.age_ns = std::min(tn - ta, tb - tn);
  const bool angles_changed = std::abs(turn_deg(a.primary_deg, b.primary_deg)) > options_.settled_tolerance_deg ||
                              std::abs(a.secondary_deg - b.secondary_deg) > options_.settled_tolerance_deg;
  // A table pan or a detector raised moves the image as much as a turn does.
  bool distances_changed = std::abs(a.sid_mm - b.sid_mm) > options_.settled_tolerance_mm ||
                           std::abs(a.sod_mm - b.sod_mm) > options_.settled_tolerance_mm;
  for (std::size_t k = 0; k < 3; ++k)
    distances_changed = distances_changed || std::abs(a.table_mm[k] - b.table_mm[k]) > options_.settled_tolerance_mm;
  // A zoom change between them: frames in between may show either field of view.
  g.moving = a.moving || b.moving || angles_changed || distances_changed || a.zoom_mode != b.zoom_mode;
  g.stale = g.age_ns > stale_ns;
  return g;
}

}  // namespace evar::acquisition
