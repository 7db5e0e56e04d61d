#pragma once
// Pairs frames with the C-arm geometry at their time. C-arm samples are kept on their own
// clock for a window; a frame's host time is mapped onto that clock by a minimum-delay
// offset estimate (so serial jitter does not move the samples) and the geometry there is
// interpolated. A frame
// is marked when the C-arm moved around it or when the geometry for it is stale.
#include <chrono>
#include <cstdint>
#include <deque>
#include <optional>

#include "evar/acquisition/carm_geometry_source.hpp"
#include "evar/acquisition/clock_offset.hpp"

namespace evar::acquisition {

struct GeometryTimelineOptions {
  std::chrono::milliseconds window{10'000};     ///< samples kept
  std::chrono::milliseconds stale_after{250};   ///< nearest sample farther than this → stale
  double settled_tolerance_deg = 0.05;          ///< neighbours' angles differing more → moving
  double settled_tolerance_mm = 0.5;            ///< neighbours' table, SID or SOD differing more → moving
  /// Two samples in a row this far behind the newest, the second going on from the first,
  /// are a restarted C-arm clock (a reboot) and start a fresh history; a single one is a
  /// stray time and is dropped. One less far behind, or a repeat, arrived late and is dropped.
  /// "Going on": its C-arm time is later, by no more than the host's time went on plus this.
  std::chrono::milliseconds restart_after{1'000};
  /// A sample that, by the clock offset so far, arrived more than this before its own time
  /// (impossible but for a clock that was set forward, or a stray time) is held likewise
  /// until the next sample confirms it. Below this, it is taken and the offset follows it.
  /// A replay faster than recorded makes every sample early by up to the gap before it:
  /// `run --replay` raises this to the session's longest C-arm gap plus 250 ms (a sparse
  /// session would otherwise lose its samples as strays).
  std::chrono::milliseconds ahead_after{250};
};

struct FrameGeometry {
  CArmState state;            ///< interpolated (angles, distances, table); flags of the nearer sample
  bool moving = false;        ///< a neighbouring sample says moving, or the angles changed between them
  bool stale = false;         ///< no sample close enough in time (link silent, or the frame is outside the history)
  std::int64_t age_ns = 0;    ///< time from the frame to its nearest sample
};

class GeometryTimeline {
 public:
  using Clock = std::chrono::steady_clock;
  explicit GeometryTimeline(GeometryTimelineOptions options = {});

  /// A sample as a CArmGeometrySource delivers it (device time and host arrival set).
  /// Two samples in a row whose device times jump (back by more than restart_after, or
  /// ahead of the clock by more than ahead_after) and then go on (a restarted or re-set
  /// C-arm clock) restart the history from them; the first is held until the second says
  /// which it is. A single jumping, late or repeated sample, or one with an absurd time
  /// (beyond ±146 years), is dropped and counted.
  void add(const CArmState& sample);
  /// The geometry at host time `t` (a frame's device_time_on_host); empty before any sample.
  std::optional<FrameGeometry> at(Clock::time_point t) const;
  /// The geometry at `carm_time_ns` on the C-arm's own clock: for frames stamped on that
  /// clock (a replayed session's frames and C-arm samples share the recording's clock, and a
  /// replay faster than recorded runs the host clock at another rate, which the host-time
  /// mapping cannot follow). Empty before any sample.
  std::optional<FrameGeometry> at_carm_time(std::int64_t carm_time_ns) const;
  /// host steady clock − C-arm clock, as estimated from the samples so far.
  std::optional<std::int64_t> carm_clock_offset_ns() const { return clock_.offset_ns(); }
  std::size_t size() const { return samples_.size(); }
  std::uint64_t dropped_samples() const { return dropped_samples_; }  ///< late, repeated or absurd
  std::uint64_t restarts() const { return restarts_; }  ///< C-arm clock jumps confirmed

 private:
  GeometryTimelineOptions options_;
  ClockOffsetEstimator clock_{256};
  std::deque<CArmState> samples_;  // in C-arm time; a query's host time is mapped onto it
  void accept(const CArmState& sample);
  bool goes_on(const CArmState& from, const CArmState& next) const;
  std::optional<CArmState> jump_candidate_;  // a far-behind or far-ahead sample, until the next one says what it is
  std::uint64_t dropped_samples_ = 0, restarts_ = 0;
};

}  // namespace evar::acquisition
