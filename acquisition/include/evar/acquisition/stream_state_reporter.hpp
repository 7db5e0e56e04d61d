#pragma once
// A source's current stream state and reason, told to its listener once per change (frame
// sources and the replay's C-arm alike). The source's own thread sets it; any thread may
// read it.
#include <functional>
#include <mutex>
#include <string>

#include "evar/acquisition/frame_source.hpp"

namespace evar::acquisition {

class StreamStateReporter {
 public:
  using Callback = std::function<void(StreamState, const std::string& reason)>;
  void listen(Callback callback) { callback_ = std::move(callback); }
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
  /// Stopped, silently, with no listener left (a source's stop()).
  void clear() {
    callback_ = nullptr;
    std::lock_guard lock(mutex_);
    state_ = StreamState::Stopped;
    reason_.clear();
  }

 private:
  Callback callback_;
  mutable std::mutex mutex_;
  StreamState state_ = StreamState::Stopped;
  std::string reason_;
};

}  // namespace evar::acquisition
