#include "evar/acquisition/stream_state.hpp"

namespace evar::acquisition {

const char* to_string(StreamState state) {
  switch (state) {
    case StreamState::Stopped: return "stopped";
    case StreamState::Connecting: return "connecting";
    case StreamState::Streaming: return "streaming";
    case StreamState::Stalled: return "stalled";
    case StreamState::Disconnected: return "disconnected";
  }
  return "unknown";
}

bool is_live(StreamState state) { return state == StreamState::Streaming; }

}  // namespace evar::acquisition
