#pragma once
// When the live video is gone, or frames come but cannot be shown, the last frame shown is
// shown again every held_frame_interval, marked as held, with the geometry it was first
// shown with: the monitor must not go on showing a frozen picture as if it were live, and
// the window must go on answering keys. The compose loop asks this what to do; the alerts
// and statistics stay the loop's.
#include <algorithm>
#include <chrono>
#include <optional>
#include <utility>

#include "evar/acquisition/frame.hpp"
#include "evar/acquisition/geometry_timeline.hpp"
#include "evar/node/frame_view.hpp"

namespace evar::node {

struct FrameField;

class HeldFramePolicy {
 public:
  using Clock = std::chrono::steady_clock;

  /// The last frame shown live, with what it was shown with.
  struct Shown {
    acquisition::Frame frame;
    std::optional<acquisition::FrameGeometry> geometry;
    std::optional<FrameView> view;
    bool size_ok = false;
    const FrameField* field = nullptr;  // the zoom mode it was shown in
  };

  HeldFramePolicy(std::chrono::milliseconds video_stall, std::chrono::milliseconds held_frame_interval)
      : video_stall_(video_stall), interval_(held_frame_interval), last_live_(Clock::now()) {}

  /// How long to wait for the next frame: `longest`, or less while stalled with a frame to
  /// hold, to wake in time for the next held frame.
  std::chrono::milliseconds wait(Clock::time_point now, std::chrono::milliseconds longest) const {
    if (!stalled_ || !shown_) return longest;
    return std::clamp(std::chrono::duration_cast<std::chrono::milliseconds>(interval_ - (now - last_held_)),
                      std::chrono::milliseconds(1), longest);
  }

  /// Frames come but cannot be shown, and a held frame is due: it is shown in their place
  /// (the next frame waits in the queue meanwhile).
  bool hold_instead_of_next(Clock::time_point now) const { return stalled_ && showing_fails_ && due(now); }

  /// True once, when no live frame has been shown for video_stall (whether none came or
  /// none could be shown).
  bool stall_begins(Clock::time_point now) {
    if (!any_live_ || stalled_ || now - last_live_ <= video_stall_) return false;
    stalled_ = true;
    return true;
  }

  /// The frame to show again and its age in seconds since it came live, when one is due.
  std::optional<double> take_held(Clock::time_point now) {
    if (!due(now)) return std::nullopt;
    last_held_ = now;
    return std::chrono::duration<double>(last_held_ - last_live_).count();
  }
  const Shown& held() const { return *shown_; }

  /// A live frame could not be shown.
  void live_failed() { showing_fails_ = true; }
  /// A live frame is on screen: the video is back, whatever kept it away. True when it
  /// ends a stall.
  bool live_shown(Clock::time_point now) {
    showing_fails_ = false;
    any_live_ = true;
    last_live_ = now;
    return std::exchange(stalled_, false);
  }
  /// Whether the frames that come cannot be shown (the stall's alert says so).
  bool showing_fails() const { return showing_fails_; }
  /// Where the frame shown live is kept, to be held later (assigning into it reuses its buffer).
  Shown& keep() {
    if (!shown_) shown_.emplace();
    return *shown_;
  }

 private:
  bool due(Clock::time_point now) const { return stalled_ && shown_ && now - last_held_ >= interval_; }

  std::chrono::milliseconds video_stall_, interval_;
  Clock::time_point last_live_;  ///< the last live frame shown
  Clock::time_point last_held_{};
  bool any_live_ = false, stalled_ = false;
  bool showing_fails_ = false;  ///< frames come but the last could not be composited
  std::optional<Shown> shown_;
};

}  // namespace evar::node
