#include "evar/acquisition/sequence_tracker.hpp"

#include <stdexcept>

namespace evar::acquisition {

SequenceTracker::SequenceTracker(int bits, std::uint64_t restart_window)
    : mask_(bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1), restart_window_(restart_window) {
  if (bits < 2 || bits > 64) throw std::invalid_argument("sequence counter width must be 2..64 bits");
}

SequenceStats& operator+=(SequenceStats& total, const SequenceStats& more) {
  total.received += more.received;
  total.dropped += more.dropped;
  total.duplicates += more.duplicates;
  total.out_of_order += more.out_of_order;
  total.restarts += more.restarts;
  return total;
}

void SequenceTracker::reset() {
  have_last_ = false;
  last_ = 0;
  stats_ = {};
}

std::uint64_t SequenceTracker::observe(std::uint64_t sequence) {
  sequence &= mask_;
  ++stats_.received;
  if (!have_last_) {
    have_last_ = true;
    last_ = sequence;
    return 0;
  }
  // Distance forward from the last number, modulo the counter width.
  const std::uint64_t forward = (sequence - last_) & mask_;
  const std::uint64_t half = mask_ / 2;
  if (forward == 0) {
    ++stats_.duplicates;
    return 0;
  }
  if (forward <= half) {
    const std::uint64_t lost = forward - 1;
    stats_.dropped += lost;
    last_ = sequence;
    return lost;
  }
  // Backwards: a small step is reordering; a large one is a device restart.
  const std::uint64_t backward = (last_ - sequence) & mask_;
  if (backward <= restart_window_) {
    ++stats_.out_of_order;
    return 0;
  }
  ++stats_.restarts;
  last_ = sequence;
  return 0;
}

}  // namespace evar::acquisition
