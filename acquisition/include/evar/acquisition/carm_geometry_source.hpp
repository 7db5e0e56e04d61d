#pragma once
// The C-arm's geometry as a stream of states, from the serial/USB link to the C-arm or
// from a replayed session. Nothing downstream knows which.
#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <string>

#include "evar/acquisition/stream_state.hpp"

namespace evar::acquisition {

struct CArmState {
  std::int64_t device_time_ns = 0;   ///< the C-arm's (or recording's) clock
  std::chrono::steady_clock::time_point host_arrival;
  double primary_deg = 0.0;          ///< DICOM: + LAO, − RAO
  double secondary_deg = 0.0;        ///< DICOM: + CRA, − CAU
  double sid_mm = 0.0, sod_mm = 0.0;
  std::array<double, 3> table_mm{};  ///< table position (x, y, z)
  bool fluoro_on = false;
  bool moving = false;               ///< geometry not settled
};

class CArmGeometrySource {
 public:
  using StateCallback = std::function<void(const CArmState&)>;
  using StreamCallback = std::function<void(StreamState, const std::string& reason)>;

  virtual ~CArmGeometrySource() = default;
  /// Starts delivering states (on the source's own thread). Throws std::runtime_error
  /// when the link cannot be opened.
  virtual void start(StateCallback on_state, StreamCallback on_stream) = 0;
  /// Stops delivery; no callback runs after stop() returns.
  virtual void stop() = 0;
  virtual StreamState state() const = 0;
  virtual std::string description() const = 0;
};

}  // namespace evar::acquisition
