#pragma once
// What every C-arm link transport (serial, USB) shares once bytes have arrived: decoding,
// the stream state (connecting → streaming → stalled / disconnected), the C-arm's status
// messages and the counters. Transports feed it bytes and tell it about their connection.
#include <chrono>
#include <map>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include "evar/acquisition/carm_geometry_source.hpp"
#include "evar/acquisition/carm_link_protocol.hpp"
#include "evar/acquisition/carm_link_statistics.hpp"

namespace evar::acquisition {

class CArmLinkReceiver {
 public:
  using Clock = std::chrono::steady_clock;
  /// Bad frames are reported at once, then summed into at most one notice per interval,
  /// and each C-arm status message repeated within it is reported once (several warnings
  /// taking turns too), so a link that spews garbage or the same warnings cannot flood the
  /// log or the screen.
  static constexpr std::chrono::seconds kNoticeInterval{10};
  /// Different status texts reported per interval at most (a peer sending ever new ones).
  static constexpr std::size_t kMaxStatusTexts = 16;
  /// `stale_after`: a streaming link that delivers no geometry for this long is Stalled.
  CArmLinkReceiver(std::string name, std::chrono::milliseconds stale_after);

  void set_callbacks(CArmGeometrySource::StateCallback on_state, CArmGeometrySource::StreamCallback on_stream,
                     CArmGeometrySource::NoticeCallback on_notice);
  /// The transport is trying to (re)connect; `reason` says why it is not up (shown to users).
  void connecting(const std::string& reason);
  /// The transport is up; the link streams once the first good sample arrives.
  void connected();
  void received(std::span<const std::uint8_t> bytes, Clock::time_point now);
  /// Call regularly (every poll timeout) so a silent link is reported as stalled.
  void tick(Clock::time_point now);
  void disconnected(const std::string& reason);
  void stopped();

  StreamState state() const;
  CArmLinkStatistics statistics() const;

 private:
  struct Change {
    StreamState state;
    std::string reason;
  };
  using Pending = std::variant<Change, LinkNotice>;  // in the order they happened
  void set_state(StreamState s, const std::string& reason);  // mutex_ held by the caller
  void report_errors(Clock::time_point now);                 // mutex_ held by the caller
  void deliver(std::unique_lock<std::mutex>& lock, const std::vector<CArmState>& samples);

  std::string name_;
  std::chrono::milliseconds stale_after_;
  CArmGeometrySource::StateCallback on_state_;
  CArmGeometrySource::StreamCallback on_stream_;
  CArmGeometrySource::NoticeCallback on_notice_;
  mutable std::mutex mutex_;
  carm_link::Decoder decoder_;
  StreamState state_ = StreamState::Stopped;
  std::string reason_;
  std::optional<Clock::time_point> last_sample_;
  std::uint64_t errors_reported_ = 0;
  std::optional<Clock::time_point> last_error_notice_;
  std::map<std::string, Clock::time_point> status_noticed_;  // each status text's last notice, within the interval
  CArmLinkStatistics stats_;
  std::vector<Pending> pending_;
};

}  // namespace evar::acquisition
