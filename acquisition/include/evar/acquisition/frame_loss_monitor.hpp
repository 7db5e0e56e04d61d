#pragma once
// Says when a source loses more than a share of its frames over a recent window: a GigE
// link dropping packets (each incomplete frame is lost), a grabber dropping buffers. The
// source's own counters are sampled; the alarm has hysteresis, so a link near the limit
// does not flicker the alert on and off.
#include <chrono>
#include <cstdint>
#include <deque>
#include <optional>

#include "evar/acquisition/sequence_tracker.hpp"

namespace evar::acquisition {

struct FrameLossOptions {
  std::chrono::milliseconds window{2000};  ///< the loss is measured over this much recent time
  double raise_fraction = 0.10;            ///< lost / (received + lost) at or above this raises the alarm
  double clear_fraction = 0.02;            ///< at or below this (over a whole window) clears it
  std::uint64_t min_frames = 10;           ///< fewer frames expected in the window: too few to judge
};

class FrameLossMonitor {
 public:
  using Clock = std::chrono::steady_clock;

  /// The loss over the window when the alarm was raised or cleared.
  struct Change {
    bool losing = false;        ///< true: raised; false: cleared
    std::uint64_t lost = 0;     ///< frames lost in the window
    std::uint64_t expected = 0; ///< received + lost in the window
    std::chrono::milliseconds span{0};  ///< the time they were counted over (up to the window)
    double fraction() const { return expected ? static_cast<double>(lost) / static_cast<double>(expected) : 0.0; }
  };

  /// Throws std::invalid_argument for a window that is not positive or fractions that are
  /// not 0 ≤ clear < raise ≤ 1.
  explicit FrameLossMonitor(FrameLossOptions options = {});

  /// Feeds the source's running counts at `now` (samples in time order). Returns the change
  /// when the alarm is raised or cleared by this sample. It is raised as soon as the frames
  /// seen (at least min_frames, the window full or not) show the loss; it is cleared only by
  /// a whole window with frames and little loss. A window without any frame clears nothing:
  /// a link so bad that whole frames are seconds apart reports its losses only when the next
  /// one comes, and must not flicker the alert (the stall alert says the rest). Counts that
  /// go backwards (a source restarted from zero) start a fresh history.
  std::optional<Change> sample(Clock::time_point now, const SequenceStats& counts);

  bool losing() const { return losing_; }

 private:
  struct Sample {
    Clock::time_point at;
    std::uint64_t received = 0, dropped = 0;
  };
  FrameLossOptions options_;
  std::deque<Sample> history_;  // oldest first; the first one at or before now − window once there is one
  bool losing_ = false;
};

}  // namespace evar::acquisition
