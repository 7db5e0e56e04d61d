#pragma once
// The C-arm link, version 2: how a C-arm-side adapter sends geometry samples and status to
// the node over a byte stream (serial or USB). docs/CARM_LINK_PROTOCOL.md is the
// specification; this header is its implementation.
//
// A message is  version u8 | type u8 | sequence u16 | body | CRC-32 u32  (little-endian),
// COBS-encoded and sent between two 0x00 bytes, so a receiver that starts mid-stream or
// meets garbage loses at most the message the garbage hit and resyncs at the next 0x00.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include "evar/acquisition/carm_geometry_source.hpp"
#include "evar/acquisition/sequence_tracker.hpp"

namespace evar::acquisition::carm_link {

/// The version encode() writes: 2, whose geometry carries the zoom mode. A receiver also
/// takes version 1 (geometry without it: zoom mode 0), which adapters without a zoom readout
/// may keep sending.
inline constexpr std::uint8_t kVersion = 2;
inline constexpr std::uint8_t kOldestVersion = 1;
/// Longest encoded message (COBS bytes, delimiter excluded) a receiver accepts.
inline constexpr std::size_t kMaxEncodedBytes = 255;
inline constexpr std::size_t kMaxStatusText = 200;

enum class MessageType : std::uint8_t { Geometry = 0x01, Status = 0x02 };
enum class StatusLevel : std::uint8_t { Info = 0, Warning = 1, Fault = 2 };
const char* to_string(StatusLevel level);

/// One geometry sample. On the wire: angles in 0.001°, distances in 0.01 mm (so a sample
/// round-trips to within half of those steps); host_arrival is not sent.
struct GeometryMessage {
  std::uint16_t sequence = 0;
  CArmState state;
};

/// The C-arm's own word on its state ("collimator moving", "tube overheated").
struct StatusMessage {
  std::uint16_t sequence = 0;
  std::int64_t device_time_ns = 0;
  StatusLevel level = StatusLevel::Info;
  std::string text;  ///< printable ASCII, at most kMaxStatusText bytes
};

using Message = std::variant<GeometryMessage, StatusMessage>;

/// The framed bytes of one message, ready to write (0x00, COBS bytes, 0x00). Throws
/// std::invalid_argument for a value the wire cannot carry (angle out of range, NaN,
/// status text too long or not printable): the sender finds out, not the receiver.
std::vector<std::uint8_t> encode(const GeometryMessage& message);
std::vector<std::uint8_t> encode(const StatusMessage& message);

/// What a receiver has seen. Every completed frame that is not a good message is counted in
/// exactly one error counter (a partial frame cut off by a reconnection is not a frame).
struct LinkStats {
  std::uint64_t bytes = 0;             ///< bytes fed
  std::uint64_t messages = 0;          ///< good messages (geometry + status)
  std::uint64_t geometry = 0, status = 0;
  std::uint64_t framing_errors = 0;    ///< invalid COBS, too short, too long
  std::uint64_t crc_errors = 0;
  std::uint64_t version_errors = 0;    ///< a protocol version this receiver does not speak
  std::uint64_t unknown_types = 0;
  std::uint64_t invalid_fields = 0;    ///< right CRC, impossible content (wrong length, range)
  SequenceStats sequence;              ///< gaps in the sender's 16-bit sequence numbers, all connections
  std::uint64_t errors() const {
    return framing_errors + crc_errors + version_errors + unknown_types + invalid_fields;
  }
};

/// Turns a byte stream into messages. Never throws on input: bad frames are counted, the
/// last one is described by last_error(), and decoding resumes at the next delimiter.
class Decoder {
 public:
  using MessageCallback = std::function<void(const Message&)>;
  /// Feeds bytes in any chunking; calls `on_message` for each good message completed.
  void feed(std::span<const std::uint8_t> bytes, const MessageCallback& on_message);
  const LinkStats& stats() const { return stats_; }
  /// "frame ending at byte 1234: (45 bytes) CRC mismatch …"; empty while all was well.
  const std::string& last_error() const { return last_error_; }
  /// Forgets a partial frame (after a reconnect); counters are kept.
  void reset_partial();
  /// A new connection: the sender may have restarted its sequence numbers. The counts of
  /// the connections before are kept in the totals.
  void reset_sequence() {
    earlier_sequence_ += sequence_.stats();
    sequence_ = SequenceTracker(16, 64);
  }

 private:
  void finish_frame(const MessageCallback& on_message);
  void fail(std::uint64_t& counter, const std::string& what);
  void accept(std::uint64_t& type_counter, std::uint16_t sequence, const Message& m, const MessageCallback& on_message);

  std::vector<std::uint8_t> frame_;
  bool overflow_ = false;
  LinkStats stats_;
  SequenceTracker sequence_{16, 64};
  SequenceStats earlier_sequence_;  // summed over the connections before this one
  std::string last_error_;
};

/// COBS (Cheshire & Baker 1999), exposed for tests and adapters. decode returns false for
/// an invalid encoding (a zero inside, a code running past the end).
std::vector<std::uint8_t> cobs_encode(std::span<const std::uint8_t> data);
bool cobs_decode(std::span<const std::uint8_t> encoded, std::vector<std::uint8_t>& out);
/// CRC-32 as in IEEE 802.3 and zlib's crc32() (reflected 0x04C11DB7, init and final xor
/// 0xFFFFFFFF): any adapter platform has it.
std::uint32_t crc32(std::span<const std::uint8_t> data);

}  // namespace evar::acquisition::carm_link
