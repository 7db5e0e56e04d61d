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
  double settled_tolerance_deg = 0.05;          ///< neighbours differing more → moving
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
  /// Samples whose device time goes backwards (a restarted C-arm clock) restart the history.
  void add(const CArmState& sample);
  /// The geometry at host time `t` (a frame's device_time_on_host); empty before any sample.
  std::optional<FrameGeometry> at(Clock::time_point t) const;
  /// host steady clock − C-arm clock, as estimated from the samples so far.
  std::optional<std::int64_t> carm_clock_offset_ns() const { return clock_.offset_ns(); }
  std::size_t size() const { return samples_.size(); }

 private:
  GeometryTimelineOptions options_;
  ClockOffsetEstimator clock_{256};
  std::deque<CArmState> samples_;  // in C-arm time; a query's host time is mapped onto it
};

}  // namespace evar::acquisition
