#include "evar/acquisition/clock_offset.hpp"

#include <algorithm>
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

}  // namespace evar::acquisition
