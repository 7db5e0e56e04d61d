#include "evar/acquisition/geometry_timeline.hpp"

#include <algorithm>
#include <cmath>

namespace evar::acquisition {

namespace {
std::int64_t ns(GeometryTimeline::Clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
}
double lerp(double a, double b, double w) { return a + (b - a) * w; }
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
  const std::int64_t restart_ns = std::chrono::nanoseconds(options_.restart_after).count();
  if (!samples_.empty() && sample.device_time_ns <= samples_.back().device_time_ns) {
    const std::int64_t behind_ns = samples_.back().device_time_ns - sample.device_time_ns;
    if (behind_ns <= restart_ns) {
      ++dropped_samples_;  // interpolation needs increasing times; the newer samples already cover it
      return;
    }
    // Far behind: a restarted C-arm clock, or one stray time (which would also spoil the
    // clock offset). The next sample decides: one going on from this one confirms the restart.
    if (!restart_candidate_ || sample.device_time_ns <= restart_candidate_->device_time_ns ||
        sample.device_time_ns - restart_candidate_->device_time_ns > restart_ns) {
      if (restart_candidate_) ++dropped_samples_;  // the one held before was a stray
      restart_candidate_ = sample;
      return;
    }
    ++restarts_;
    samples_.clear();
    clock_.reset();
    clock_.add(restart_candidate_->device_time_ns, ns(restart_candidate_->host_arrival));
    samples_.push_back(*restart_candidate_);
    restart_candidate_.reset();
  } else if (restart_candidate_) {
    ++dropped_samples_;  // the far-behind sample held was a stray: the clock went on
    restart_candidate_.reset();
  }
  clock_.add(sample.device_time_ns, ns(sample.host_arrival));
  samples_.push_back(sample);
  const std::int64_t oldest = sample.device_time_ns - std::chrono::nanoseconds(options_.window).count();
  while (samples_.size() > 2 && samples_.front().device_time_ns < oldest) samples_.pop_front();
}

std::optional<FrameGeometry> GeometryTimeline::at(Clock::time_point t) const {
  if (samples_.empty()) return std::nullopt;
  // The frame's time on the C-arm clock, by the newest offset estimate.
  const std::int64_t tn = ns(t) - *clock_.offset_ns();
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
  g.state.primary_deg = lerp(a.primary_deg, b.primary_deg, w);
  g.state.secondary_deg = lerp(a.secondary_deg, b.secondary_deg, w);
  g.state.sid_mm = lerp(a.sid_mm, b.sid_mm, w);
  g.state.sod_mm = lerp(a.sod_mm, b.sod_mm, w);
  for (std::size_t k = 0; k < 3; ++k) g.state.table_mm[k] = lerp(a.table_mm[k], b.table_mm[k], w);
  g.age_ns = std::min(tn - ta, tb - tn);
  const bool angles_changed = std::abs(a.primary_deg - b.primary_deg) > options_.settled_tolerance_deg ||
                              std::abs(a.secondary_deg - b.secondary_deg) > options_.settled_tolerance_deg;
  g.moving = a.moving || b.moving || angles_changed;
  g.stale = g.age_ns > stale_ns;
  return g;
}

}  // namespace evar::acquisition
