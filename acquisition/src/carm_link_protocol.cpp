#include "evar/acquisition/carm_link_protocol.hpp"

#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace evar::acquisition::carm_link {

namespace {

constexpr std::size_t kHeaderBytes = 4;         // version, type, sequence
constexpr std::size_t kCrcBytes = 4;
constexpr std::size_t kGeometryBodyBytesV1 = 37;  // see docs/CARM_LINK_PROTOCOL.md
constexpr std::size_t kGeometryBodyBytes = 38;    // version 2: and the zoom mode
constexpr std::size_t kStatusFixedBytes = 10;   // time, level, text length
constexpr double kMilliDegPerDeg = 1000.0;
constexpr double kCentiMmPerMm = 100.0;
constexpr std::uint8_t kFlagFluoro = 0x01, kFlagMoving = 0x02;

std::array<std::uint32_t, 256> make_crc_table() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    table[i] = c;
  }
  return table;
}

class Writer {
 public:
  void u8(std::uint8_t v) { bytes.push_back(v); }
  void u16(std::uint16_t v) { put(v, 2); }
  void u32(std::uint32_t v) { put(v, 4); }
  void i32(std::int32_t v) { put(static_cast<std::uint32_t>(v), 4); }
  void i64(std::int64_t v) { put(static_cast<std::uint64_t>(v), 8); }
  std::vector<std::uint8_t> bytes;

 private:
  void put(std::uint64_t v, int n) {
    for (int i = 0; i < n; ++i) bytes.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
};

class Reader {
 public:
  explicit Reader(std::span<const std::uint8_t> b) : b_(b) {}
  std::uint8_t u8() { return static_cast<std::uint8_t>(get(1)); }
  std::uint16_t u16() { return static_cast<std::uint16_t>(get(2)); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(get(4)); }
  std::int32_t i32() { return static_cast<std::int32_t>(static_cast<std::uint32_t>(get(4))); }
  std::int64_t i64() { return static_cast<std::int64_t>(get(8)); }
  std::size_t offset() const { return pos_; }

 private:
  std::uint64_t get(int n) {  // callers check lengths first
    std::uint64_t v = 0;
    for (int i = 0; i < n; ++i) v |= static_cast<std::uint64_t>(b_[pos_ + static_cast<std::size_t>(i)]) << (8 * i);
    pos_ += static_cast<std::size_t>(n);
    return v;
  }
  std::span<const std::uint8_t> b_;
  std::size_t pos_ = 0;
};

// Rounds a physical value to its wire unit, refusing what the field cannot hold.
std::int64_t to_wire(double value, double per_unit, double limit, const char* field) {
  if (!std::isfinite(value) || std::abs(value) > limit)
    throw std::invalid_argument(std::string("C-arm link: ") + field + " = " + std::to_string(value) +
                                " cannot be sent (limit ±" + std::to_string(limit) + ")");
  return std::llround(value * per_unit);
}

std::vector<std::uint8_t> frame(Writer& w) {
  w.u32(crc32(w.bytes));
  // A delimiter on both sides: garbage or a torn frame before this one costs only itself.
  std::vector<std::uint8_t> out{0x00};
  const std::vector<std::uint8_t> body = cobs_encode(w.bytes);
  out.insert(out.end(), body.begin(), body.end());
  out.push_back(0x00);
  return out;
}

std::string hex32(std::uint32_t v) {
  char s[11];
  std::snprintf(s, sizeof s, "0x%08x", v);
  return s;
}

bool printable(const std::string& s) {
  for (unsigned char c : s)
    if (c < 0x20 || c > 0x7e) return false;
  return true;
}

}  // namespace

const char* to_string(StatusLevel level) {
  switch (level) {
    case StatusLevel::Info: return "info";
    case StatusLevel::Warning: return "warning";
    case StatusLevel::Fault: return "fault";
  }
  return "?";
}

std::uint32_t crc32(std::span<const std::uint8_t> data) {
  static const std::array<std::uint32_t, 256> table = make_crc_table();
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::uint8_t b : data) c = table[(c ^ b) & 0xFFu] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

std::vector<std::uint8_t> cobs_encode(std::span<const std::uint8_t> data) {
  std::vector<std::uint8_t> out;
  out.reserve(data.size() + data.size() / 254 + 2);
  std::size_t code_at = out.size();
  out.push_back(0);
  std::uint8_t code = 1;
  for (std::uint8_t b : data) {
    if (b == 0) {
      out[code_at] = code;
      code_at = out.size();
      out.push_back(0);
      code = 1;
      continue;
    }
    out.push_back(b);
    if (++code == 0xFF) {  // a full block of 254 non-zero bytes has no implied zero
      out[code_at] = code;
      code_at = out.size();
      out.push_back(0);
      code = 1;
    }
  }
  out[code_at] = code;
  return out;
}

bool cobs_decode(std::span<const std::uint8_t> encoded, std::vector<std::uint8_t>& out) {
  out.clear();
  std::size_t i = 0;
  while (i < encoded.size()) {
    const std::uint8_t code = encoded[i++];
    if (code == 0) return false;
    if (i + code - 1 > encoded.size()) return false;
    for (std::uint8_t k = 1; k < code; ++k) {
      if (encoded[i] == 0) return false;
      out.push_back(encoded[i++]);
    }
    if (code != 0xFF && i < encoded.size()) out.push_back(0);
  }
  return true;
}

std::vector<std::uint8_t> encode(const GeometryMessage& m) {
  const CArmState& s = m.state;
  Writer w;
  w.u8(kVersion);
  w.u8(static_cast<std::uint8_t>(MessageType::Geometry));
  w.u16(m.sequence);
  w.i64(s.device_time_ns);
  w.i32(static_cast<std::int32_t>(to_wire(s.primary_deg, kMilliDegPerDeg, 180.0, "primary_deg")));
  w.i32(static_cast<std::int32_t>(to_wire(s.secondary_deg, kMilliDegPerDeg, 90.0, "secondary_deg")));
  // Checked on the wire values: what the receiver will check.
  const std::int64_t sid = to_wire(s.sid_mm, kCentiMmPerMm, 4.0e7, "sid_mm");
  const std::int64_t sod = to_wire(s.sod_mm, kCentiMmPerMm, 4.0e7, "sod_mm");
  if (!(sod > 0) || !(sod < sid))
    throw std::invalid_argument("C-arm link: need 0 < sod_mm < sid_mm in 0.01 mm steps (got sod " +
                                std::to_string(s.sod_mm) + ", sid " + std::to_string(s.sid_mm) + ")");
  w.u32(static_cast<std::uint32_t>(sid));
  w.u32(static_cast<std::uint32_t>(sod));
  const char* table_names[3] = {"table_mm[0]", "table_mm[1]", "table_mm[2]"};
  for (int k = 0; k < 3; ++k)
    w.i32(static_cast<std::int32_t>(to_wire(s.table_mm[static_cast<std::size_t>(k)], kCentiMmPerMm, 2.0e7, table_names[k])));
  w.u8(static_cast<std::uint8_t>((s.fluoro_on ? kFlagFluoro : 0) | (s.moving ? kFlagMoving : 0)));
  if (s.zoom_mode < 0 || s.zoom_mode > 255)
    throw std::invalid_argument("C-arm link: zoom_mode " + std::to_string(s.zoom_mode) + " outside 0-255");
  w.u8(static_cast<std::uint8_t>(s.zoom_mode));
  return frame(w);
}

std::vector<std::uint8_t> encode(const StatusMessage& m) {
  if (m.text.size() > kMaxStatusText)
    throw std::invalid_argument("C-arm link: status text of " + std::to_string(m.text.size()) + " bytes (at most " +
                                std::to_string(kMaxStatusText) + ")");
  if (!printable(m.text)) throw std::invalid_argument("C-arm link: status text must be printable ASCII");
  if (static_cast<int>(m.level) > 2) throw std::invalid_argument("C-arm link: unknown status level");
  Writer w;
  w.u8(kVersion);
  w.u8(static_cast<std::uint8_t>(MessageType::Status));
  w.u16(m.sequence);
  w.i64(m.device_time_ns);
  w.u8(static_cast<std::uint8_t>(m.level));
  w.u8(static_cast<std::uint8_t>(m.text.size()));
  for (char c : m.text) w.u8(static_cast<std::uint8_t>(c));
  return frame(w);
}

void Decoder::reset_partial() {
  frame_.clear();
  overflow_ = false;
}

void Decoder::fail(std::uint64_t& counter, const std::string& what) {
  ++counter;
  last_error_ = "frame ending at byte " + std::to_string(stats_.bytes - 1) + ": " + what;
}

void Decoder::accept(std::uint64_t& type_counter, std::uint16_t sequence, const Message& m,
                     const MessageCallback& on_message) {
  ++stats_.messages;
  ++type_counter;
  sequence_.observe(sequence);
  stats_.sequence = earlier_sequence_;
  stats_.sequence += sequence_.stats();
  on_message(m);
}

void Decoder::feed(std::span<const std::uint8_t> bytes, const MessageCallback& on_message) {
  for (std::uint8_t b : bytes) {
    ++stats_.bytes;
    if (b != 0x00) {
      if (frame_.size() < kMaxEncodedBytes)
        frame_.push_back(b);
      else
        overflow_ = true;
      continue;
    }
    if (overflow_)
      fail(stats_.framing_errors, "longer than " + std::to_string(kMaxEncodedBytes) + " bytes (no delimiter)");
    else if (!frame_.empty())
      finish_frame(on_message);
    reset_partial();
  }
}

void Decoder::finish_frame(const MessageCallback& on_message) {
  std::vector<std::uint8_t> p;
  std::string size = "(";  // built in steps: g++ 12 warns falsely (-Wrestrict) on "(" + std::string
  size += std::to_string(frame_.size());
  size += " bytes) ";
  if (!cobs_decode(frame_, p)) return fail(stats_.framing_errors, size + "invalid COBS encoding");
  if (p.size() < kHeaderBytes + kCrcBytes)
    return fail(stats_.framing_errors, size + "too short for a message (" + std::to_string(p.size()) + " decoded bytes)");
  const std::size_t n = p.size() - kCrcBytes;
  const std::span<const std::uint8_t> bytes(p);
  const std::uint32_t said = Reader(bytes.subspan(n)).u32();
  const std::uint32_t computed = crc32(bytes.first(n));
  if (said != computed)
    return fail(stats_.crc_errors, size + "CRC mismatch: frame says " + hex32(said) + ", bytes give " + hex32(computed));
  Reader r(bytes.first(n));
  const std::uint8_t version = r.u8();
  if (version < kOldestVersion || version > kVersion)
    return fail(stats_.version_errors, size + "protocol version " + std::to_string(version) + " (this node speaks " +
                                           std::to_string(kOldestVersion) + " to " + std::to_string(kVersion) + ")");
  const std::uint8_t type = r.u8();
  const std::uint16_t sequence = r.u16();
  const std::size_t body = n - kHeaderBytes;
  auto wrong_length = [&](const char* what, std::size_t expected) {
    fail(stats_.invalid_fields, size + what + " body of " + std::to_string(body) + " bytes (expected " +
                                    std::to_string(expected) + ")");
  };

  if (type == static_cast<std::uint8_t>(MessageType::Geometry)) {
    const std::size_t expected = version == 1 ? kGeometryBodyBytesV1 : kGeometryBodyBytes;
    if (body != expected) return wrong_length(version == 1 ? "version 1 geometry" : "geometry", expected);
    GeometryMessage m;
    m.sequence = sequence;
    CArmState& s = m.state;
    s.device_time_ns = r.i64();
    const std::int32_t primary = r.i32(), secondary = r.i32();
    const std::uint32_t sid = r.u32(), sod = r.u32();
    std::array<std::int32_t, 3> table{};
    for (auto& t : table) t = r.i32();
    const std::uint8_t flags = r.u8();
    const std::uint8_t zoom_mode = version == 1 ? 0 : r.u8();
    if (primary < -180000 || primary > 180000)
      return fail(stats_.invalid_fields, size + "primary angle " + std::to_string(primary) + " m° outside ±180°");
    if (secondary < -90000 || secondary > 90000)
      return fail(stats_.invalid_fields, size + "secondary angle " + std::to_string(secondary) + " m° outside ±90°");
    if (sid == 0 || sod == 0 || sod >= sid)
      return fail(stats_.invalid_fields, size + "need 0 < SOD < SID (SOD " + std::to_string(sod) + ", SID " +
                                             std::to_string(sid) + ", in 0.01 mm)");
    if ((flags & ~(kFlagFluoro | kFlagMoving)) != 0)
      return fail(stats_.invalid_fields, size + "reserved flag bits set (flags " + std::to_string(flags) + ")");
    s.primary_deg = primary / kMilliDegPerDeg;
    s.secondary_deg = secondary / kMilliDegPerDeg;
    s.sid_mm = sid / kCentiMmPerMm;
    s.sod_mm = sod / kCentiMmPerMm;
    for (std::size_t k = 0; k < 3; ++k) s.table_mm[k] = table[k] / kCentiMmPerMm;
    s.fluoro_on = (flags & kFlagFluoro) != 0;
    s.moving = (flags & kFlagMoving) != 0;
    s.zoom_mode = zoom_mode;
    return accept(stats_.geometry, sequence, Message{m}, on_message);
  }
  if (type == static_cast<std::uint8_t>(MessageType::Status)) {
    if (body < kStatusFixedBytes) return wrong_length("status", kStatusFixedBytes);
    StatusMessage m;
    m.sequence = sequence;
    m.device_time_ns = r.i64();
    const std::uint8_t level = r.u8();
    const std::uint8_t length = r.u8();
    if (body != kStatusFixedBytes + length) return wrong_length("status", kStatusFixedBytes + length);
    if (level > 2) return fail(stats_.invalid_fields, size + "status level " + std::to_string(level) + " unknown");
    for (std::uint8_t k = 0; k < length; ++k) m.text.push_back(static_cast<char>(r.u8()));
    if (length > kMaxStatusText || !printable(m.text))
      return fail(stats_.invalid_fields, size + "status text too long or not printable ASCII");
    m.level = static_cast<StatusLevel>(level);
    return accept(stats_.status, sequence, Message{m}, on_message);
  }
  fail(stats_.unknown_types, size + "unknown message type " + std::to_string(type));
}

}  // namespace evar::acquisition::carm_link
