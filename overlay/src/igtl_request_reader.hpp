#pragma once
// Splits a client's OpenIGTLink byte stream into messages by their headers: 58 bytes,
// big-endian: version (2), type (12), device name (20), timestamp (8), body size (8), CRC
// (8). A request (GET_IMAGE, GET_STATUS, ...) is handed out once its body, empty in
// practice, is whole. Other messages (a client may push data at the node) are handed out
// by their header and their bodies read past as they stream in, never buffered. A request
// announcing a body larger than any request has is garbage: the reader stops there, and
// the server lets that client go rather than buffer for it.
#include <cstdint>
#include <string>
#include <vector>

namespace evar::overlay {

struct IgtlMessageHeader {
  std::string type;          ///< e.g. "GET_IMAGE", "IMAGE" (up to 12 characters, NULs cut)
  std::string device;        ///< up to 20 characters, NULs cut
  std::uint64_t body_bytes = 0;
  bool request() const { return type.rfind("GET_", 0) == 0; }
};

class IgtlRequestReader {
 public:
  static constexpr std::size_t kHeaderBytes = 58;
  static constexpr std::uint64_t kMaxRequestBodyBytes = std::uint64_t{1} << 20;

  /// Reads `size` more bytes and appends the headers of the messages they complete, in
  /// order. Returns false once the stream turned out to be garbage (nothing more is read).
  bool feed(const std::uint8_t* data, std::size_t size, std::vector<IgtlMessageHeader>& out);

  bool garbage() const { return garbage_; }
  /// Bytes held for a message not yet whole: under kHeaderBytes + kMaxRequestBodyBytes.
  std::size_t buffered() const { return in_.size(); }

 private:
  std::vector<std::uint8_t> in_;  // a header or request not yet whole
  std::uint64_t skip_ = 0;        // body bytes still to come of a message that is not a request
  bool garbage_ = false;
};

}  // namespace evar::overlay
