#include "evar/acquisition/frame.hpp"
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

int bytes_per_pixel(PixelFormat format) { return format == PixelFormat::Mono8 ? 1 : 2; }

const char* to_string(PixelFormat format) {
  switch (format) {
    case PixelFormat::Mono8: return "Mono8";
    case PixelFormat::Mono12: return "Mono12";
    case PixelFormat::Mono16: return "Mono16";
  }
  return "unknown";
}

}  // namespace evar::acquisition
