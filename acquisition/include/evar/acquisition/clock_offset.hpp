#pragma once
// The offset between a device's clock and the host's, from pairs (device time, host arrival
// time). Each pair's difference is the true offset plus a non-negative transport and
// scheduling delay, so the smallest difference in a recent window is the best estimate
// (the minimum filter of NTP and PTP); the spread above it is the delay jitter.
#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <span>
#include <vector>

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

/// One sample of a device's clock: its own time and when the host received it.
struct ClockPair {
  std::int64_t device_ns = 0;
  std::int64_t host_ns = 0;
};

/// The offline estimate, for a recording that has all its samples: per sample, device time
/// plus the smallest arrival delay among the samples within ±`window_ns` of device time
/// around it, earlier and later ones alike (the online estimator sees only the past, so the
/// first samples of a stream carry its start-up delays). A clock that goes back or jumps
/// ahead by more than `jump_ns` (delays only ever raise the difference) starts a new stretch
/// with its own offset. The result is in input order and never decreases.
std::vector<std::int64_t> device_times_on_host(std::span<const ClockPair> samples,
                                               std::int64_t window_ns = 30'000'000'000,
                                               std::int64_t jump_ns = 1'000'000'000);

}  // namespace evar::acquisition
