#pragma once
// The offset between a device's clock and the host's, from pairs (device time, host arrival
// time). Each pair's difference is the true offset plus a non-negative transport and
// scheduling delay, so the smallest difference in a recent window is the best estimate
// (the minimum filter of NTP and PTP); the spread above it is the delay jitter.
#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>

namespace evar::acquisition {

class ClockOffsetEstimator {
 public:
  explicit ClockOffsetEstimator(std::size_t window = 256);
  void add(std::int64_t device_ns, std::int64_t host_ns);
  /// host ≈ device + offset; empty before the first pair.
  std::optional<std::int64_t> offset_ns() const;
  /// Median delay above the minimum over the window (how late samples arrive, typically).
  std::optional<std::int64_t> typical_delay_ns() const;
  std::int64_t to_host_ns(std::int64_t device_ns) const;  ///< throws std::logic_error before the first pair
  void reset() { diffs_.clear(); }

 private:
  std::size_t window_;
  std::deque<std::int64_t> diffs_;
};

}  // namespace evar::acquisition
