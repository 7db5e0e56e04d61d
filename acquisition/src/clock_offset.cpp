#include "evar/acquisition/clock_offset.hpp"

#include <algorithm>
#include <set>
#include <stdexcept>
#include <vector>

namespace evar::acquisition {

ClockOffsetEstimator::ClockOffsetEstimator(std::size_t window) : window_(window) {
  if (window == 0) throw std::invalid_argument("clock offset: the window must hold at least one sample");
}

void ClockOffsetEstimator::add(std::int64_t device_ns, std::int64_t host_ns) {
  diffs_.push_back(host_ns - device_ns);
  if (diffs_.size() > window_) diffs_.pop_front();
}

std::optional<std::int64_t> ClockOffsetEstimator::offset_ns() const {
  if (diffs_.empty()) return std::nullopt;
  return *std::min_element(diffs_.begin(), diffs_.end());
}

std::optional<std::int64_t> ClockOffsetEstimator::typical_delay_ns() const {
  if (diffs_.empty()) return std::nullopt;
  std::vector<std::int64_t> d(diffs_.begin(), diffs_.end());
  const std::int64_t lo = *std::min_element(d.begin(), d.end());
  auto mid = d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2);
  std::nth_element(d.begin(), mid, d.end());
  return *mid - lo;
}

std::int64_t ClockOffsetEstimator::to_host_ns(std::int64_t device_ns) const {
  const auto o = offset_ns();
  if (!o) throw std::logic_error("clock offset: no samples yet");
  return device_ns + *o;
}

std::vector<std::int64_t> device_times_on_host(std::span<const ClockPair> samples, std::int64_t window_ns,
                                               std::int64_t jump_ns) {
  if (window_ns < 0 || jump_ns <= 0) throw std::invalid_argument("clock offset: window and jump must be positive");
  const std::size_t n = samples.size();
  std::vector<std::int64_t> diff(n);
  for (std::size_t i = 0; i < n; ++i) diff[i] = samples[i].host_ns - samples[i].device_ns;
  std::vector<std::int64_t> out;
  out.reserve(n);
  std::size_t begin = 0;
  while (begin < n) {
    std::size_t end = begin + 1;
    while (end < n && samples[end].device_ns >= samples[end - 1].device_ns && diff[end] > diff[end - 1] - jump_ns) ++end;
    std::multiset<std::int64_t> window;  // diffs of the samples within ±window_ns of sample i
    std::size_t lo = begin, hi = begin;
    for (std::size_t i = begin; i < end; ++i) {
      while (hi < end && samples[hi].device_ns <= samples[i].device_ns + window_ns) window.insert(diff[hi++]);
      while (samples[lo].device_ns < samples[i].device_ns - window_ns) window.erase(window.find(diff[lo++]));
      std::int64_t t = samples[i].device_ns + *window.begin();
      if (!out.empty()) t = std::max(t, out.back());
      out.push_back(t);
    }
    begin = end;
  }
  return out;
}

}  // namespace evar::acquisition
