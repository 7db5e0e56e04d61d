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
  if (!samples_.empty() && sample.device_time_ns < samples_.back().state.device_time_ns) {
    samples_.clear();
    clock_.reset();
  }
  clock_.add(sample.device_time_ns, ns(sample.host_arrival));
  // Every kept sample is re-placed with the newest offset, so one late first sample does
  // not leave the history shifted.
  const std::int64_t offset = *clock_.offset_ns();
  samples_.push_back({sample.device_time_ns + offset, sample});
  for (auto& p : samples_) p.host_ns = p.state.device_time_ns + offset;
  const std::int64_t oldest = samples_.back().host_ns - std::chrono::nanoseconds(options_.window).count();
  while (samples_.size() > 2 && samples_.front().host_ns < oldest) samples_.pop_front();
}

std::optional<FrameGeometry> GeometryTimeline::at(Clock::time_point t) const {
  if (samples_.empty()) return std::nullopt;
  const std::int64_t tn = ns(t);
  const std::int64_t stale_ns = std::chrono::nanoseconds(options_.stale_after).count();
  auto after = std::lower_bound(samples_.begin(), samples_.end(), tn,
                                [](const Placed& p, std::int64_t v) { return p.host_ns < v; });
  FrameGeometry g;
  if (after == samples_.begin() || after == samples_.end()) {
    // Outside the history: hold the end sample; stale when it is too far away.
    const Placed& p = after == samples_.begin() ? samples_.front() : samples_.back();
    g.state = p.state;
    g.age_ns = std::llabs(tn - p.host_ns);
    g.moving = p.state.moving;
    g.stale = g.age_ns > stale_ns;
    return g;
  }
  const Placed& b = *after;
  const Placed& a = *(after - 1);
  const double w = b.host_ns > a.host_ns ? static_cast<double>(tn - a.host_ns) / static_cast<double>(b.host_ns - a.host_ns) : 0.0;
  g.state = w < 0.5 ? a.state : b.state;  // flags and times of the nearer sample
  g.state.primary_deg = lerp(a.state.primary_deg, b.state.primary_deg, w);
  g.state.secondary_deg = lerp(a.state.secondary_deg, b.state.secondary_deg, w);
  g.state.sid_mm = lerp(a.state.sid_mm, b.state.sid_mm, w);
  g.state.sod_mm = lerp(a.state.sod_mm, b.state.sod_mm, w);
  for (std::size_t k = 0; k < 3; ++k) g.state.table_mm[k] = lerp(a.state.table_mm[k], b.state.table_mm[k], w);
  g.age_ns = std::min(tn - a.host_ns, b.host_ns - tn);
  const bool angles_changed = std::abs(a.state.primary_deg - b.state.primary_deg) > options_.settled_tolerance_deg ||
                              std::abs(a.state.secondary_deg - b.state.secondary_deg) > options_.settled_tolerance_deg;
  g.moving = a.state.moving || b.state.moving || angles_changed;
  g.stale = g.age_ns > stale_ns;
  return g;
}

}  // namespace evar::acquisition
