#pragma once
// A frame source's current state and reason, told to its listener once per change. The
// source's own thread sets it; any thread may read it.
#include <mutex>
#include <string>

#include "evar/acquisition/frame_source.hpp"

namespace evar::acquisition {

class StreamStateReporter {
 public:
  void listen(FrameSource::StateCallback callback) { callback_ = std::move(callback); }
  /// Records the state and tells the listener (outside the lock) when it changed.
  void set(StreamState s, const std::string& why) {
    {
      std::lock_guard lock(mutex_);
      if (s == state_ && why == reason_) return;
      state_ = s;
      reason_ = why;
    }
    if (callback_) callback_(s, why);
  }
  StreamState state() const {
    std::lock_guard lock(mutex_);
    return state_;
  }

 private:
  FrameSource::StateCallback callback_;
  mutable std::mutex mutex_;
  StreamState state_ = StreamState::Stopped;
  std::string reason_;
};

}  // namespace evar::acquisition
