#pragma once
// The interface the node consumes frames through. GigE (Aravis), V4L2 and the replay of
// recorded sessions (sim/) implement it; nothing downstream knows which one it has.
#include <functional>
#include <string>

#include "evar/acquisition/frame.hpp"
#include "evar/acquisition/sequence_tracker.hpp"
#include "evar/acquisition/stream_state.hpp"

namespace evar::acquisition {

class FrameSource {
 public:
  using FrameCallback = std::function<void(const Frame&)>;
  using StateCallback = std::function<void(StreamState, const std::string& reason)>;

  virtual ~FrameSource() = default;
  /// Starts delivering frames to `on_frame` (on the source's own thread) and state changes
  /// to `on_state`. Throws std::runtime_error when the source cannot be opened.
  virtual void start(FrameCallback on_frame, StateCallback on_state) = 0;
  /// Stops delivery; no callback runs after stop() returns.
  virtual void stop() = 0;
  virtual StreamState state() const = 0;
  /// Frames received and lost so far (from sequence-number gaps).
  virtual SequenceStats statistics() const = 0;
  /// Human-readable identity ("GigE camera Aravis-Fake-GV01", "replay session-01").
  virtual std::string description() const = 0;
};

}  // namespace evar::acquisition
