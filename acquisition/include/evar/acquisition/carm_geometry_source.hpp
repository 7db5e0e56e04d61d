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

/// Where the C-arm stands and whether it images: the C-arm state as every layer knows it.
/// A live state (CArmState) adds its clocks; a session's sample (session::CArmSample) its
/// time on the host clock; the wire (carm_link::GeometryMessage) carries a CArmState.
struct CArmPose {
  double primary_deg = 0.0;          ///< DICOM: + LAO, − RAO
  double secondary_deg = 0.0;        ///< DICOM: + CRA, − CAU
  double sid_mm = 0.0, sod_mm = 0.0;
  std::array<double, 3> table_mm{};  ///< table position (x, y, z)
  bool fluoro_on = false;
  bool moving = false;               ///< geometry not settled
  /// The C-arm's zoom (magnification, field-of-view) mode as the link numbers it, 1-255;
  /// 0: not said (a link of protocol version 1, or a C-arm without zoom modes).
  int zoom_mode = 0;
};

struct CArmState : CArmPose {
  std::int64_t device_time_ns = 0;   ///< the C-arm's (or recording's) clock
  std::chrono::steady_clock::time_point host_arrival;
};

/// News from a link that changes no state: bad frames on a line that still delivers, a
/// warning or fault the C-arm itself reports. The text is worded to stand alone on screen
/// ("C-arm link serial /dev/ttyUSB0: 12 bad frames …", "C-arm warning: …").
struct LinkNotice {
  enum class Kind { BadFrames, CArmStatus };
  Kind kind = Kind::BadFrames;
  std::string text;
};

class CArmGeometrySource {
 public:
  using StateCallback = std::function<void(const CArmState&)>;
  /// Each change of the link's state, with the reason (shown to users).
  using StreamCallback = std::function<void(StreamState, const std::string& reason)>;
  /// News that changes no state (LinkNotice); a source rate-limits its notices, so each
  /// may be shown and logged.
  using NoticeCallback = std::function<void(const LinkNotice& notice)>;

  virtual ~CArmGeometrySource() = default;
  /// Starts delivering states (on the source's own thread); any callback may be empty.
  /// Throws std::runtime_error when the link cannot be opened.
  virtual void start(StateCallback on_state, StreamCallback on_stream, NoticeCallback on_notice) = 0;
  /// Stops delivery; no callback runs after stop() returns.
  virtual void stop() = 0;
  virtual StreamState state() const = 0;
  virtual std::string description() const = 0;
};

}  // namespace evar::acquisition
