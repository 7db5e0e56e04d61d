#pragma once
// The life cycle every source reports (CustusX-style honesty: a stalled stream is never
// shown as live).
namespace evar::acquisition {

enum class StreamState { Stopped, Connecting, Streaming, Stalled, Disconnected };

const char* to_string(StreamState state);

/// True when frames from a source in this state may be presented as live.
bool is_live(StreamState state);

}  // namespace evar::acquisition
