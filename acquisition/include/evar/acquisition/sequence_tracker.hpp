#pragma once
// Counts received, dropped, duplicated and out-of-order frames from device sequence
// numbers, which is how every grabber reports drops (V4L2 sequence, GigE block id,
// replay index).
#include <cstdint>

namespace evar::acquisition {

struct SequenceStats {
  std::uint64_t received = 0;       ///< frames delivered
  std::uint64_t dropped = 0;        ///< numbers skipped by forward gaps
  std::uint64_t duplicates = 0;     ///< the same number again
  std::uint64_t out_of_order = 0;   ///< a number below the last one (not a restart)
  std::uint64_t restarts = 0;       ///< the device restarted its counter
};

/// Sums counts across connections (each connection has its own device counter).
SequenceStats& operator+=(SequenceStats& total, const SequenceStats& more);

class SequenceTracker {
 public:
  /// `bits`: width of the device counter (it wraps at 2^bits); `restart_window`: a
  /// backward jump larger than this is taken as a counter restart, not reordering.
  explicit SequenceTracker(int bits = 64, std::uint64_t restart_window = 1024);

  /// Records one frame's sequence number; returns how many frames were lost just before it.
  std::uint64_t observe(std::uint64_t sequence);
  const SequenceStats& stats() const { return stats_; }
  void reset();

 private:
  std::uint64_t mask_;
  std::uint64_t restart_window_;
  bool have_last_ = false;
  std::uint64_t last_ = 0;
  SequenceStats stats_;
};

}  // namespace evar::acquisition
