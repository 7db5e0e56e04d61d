#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <variant>
#include <vector>

#include "evar/acquisition/carm_link_protocol.hpp"

namespace wire = evar::acquisition::carm_link;
using Bytes = std::vector<std::uint8_t>;

namespace {

wire::GeometryMessage sample(std::uint16_t seq) {
  wire::GeometryMessage m;
  m.sequence = seq;
  m.state.device_time_ns = 1'700'000'000'000'000'000LL + seq * 100'000'000LL;
  m.state.primary_deg = -35.1234 + 0.5 * (seq % 100);
  m.state.secondary_deg = 12.3456;
  m.state.sid_mm = 1195.123;
  m.state.sod_mm = 785.456;
  m.state.table_mm = {-12.345, 250.5, -1000.004};
  m.state.fluoro_on = seq % 2 == 0;
  m.state.moving = seq % 3 == 0;
  m.state.zoom_mode = 1 + seq % 4;
  return m;
}

std::vector<wire::Message> decode_all(wire::Decoder& d, const Bytes& bytes) {
  std::vector<wire::Message> out;
  d.feed(bytes, [&](const wire::Message& m) { out.push_back(m); });
  return out;
}

void append(Bytes& a, const Bytes& b) { a.insert(a.end(), b.begin(), b.end()); }

// A message with a valid CRC and whatever content, as a broken or newer adapter might send.
Bytes raw_frame(Bytes payload) {
  const std::uint32_t crc = wire::crc32(payload);
  for (int i = 0; i < 4; ++i) payload.push_back(static_cast<std::uint8_t>(crc >> (8 * i)));
  Bytes out{0};
  append(out, wire::cobs_encode(payload));
  out.push_back(0);
  return out;
}

}  // namespace

TEST(CArmLinkProtocol, Crc32IsTheIeeeOne) {
  const std::string check = "123456789";  // the standard check value
  EXPECT_EQ(wire::crc32(Bytes(check.begin(), check.end())), 0xCBF43926u);
}

TEST(CArmLinkProtocol, CobsRoundTripsAnyBytesWithoutZeros) {
  std::mt19937 rng(7);
  for (std::size_t n : {0u, 1u, 2u, 253u, 254u, 255u, 256u, 508u, 509u, 600u}) {
    for (int zero_share : {0, 10, 100}) {
      Bytes data(n);
      for (auto& b : data) b = static_cast<std::uint8_t>(static_cast<int>(rng() % 100) < zero_share ? 0 : 1 + rng() % 255);
      const Bytes enc = wire::cobs_encode(data);
      for (auto b : enc) ASSERT_NE(b, 0) << "n=" << n;
      EXPECT_LE(enc.size(), n + n / 254 + 1);
      Bytes dec;
      ASSERT_TRUE(wire::cobs_decode(enc, dec));
      EXPECT_EQ(dec, data) << "n=" << n << " zeros " << zero_share << "%";
    }
  }
  Bytes out;
  EXPECT_FALSE(wire::cobs_decode(Bytes{5, 1, 2}, out));  // code runs past the end
  EXPECT_FALSE(wire::cobs_decode(Bytes{2, 0}, out));     // zero inside
}

TEST(CArmLinkProtocol, GeometryRoundTripsToTheWireResolution) {
  wire::Decoder d;
  for (std::uint16_t seq : {0, 1, 2, 3, 65535}) {
    const auto m = sample(seq);
    const auto got = decode_all(d, wire::encode(m));
    ASSERT_EQ(got.size(), 1u);
    const auto& g = std::get<wire::GeometryMessage>(got[0]);
    EXPECT_EQ(g.sequence, seq);
    EXPECT_EQ(g.state.device_time_ns, m.state.device_time_ns);
    EXPECT_NEAR(g.state.primary_deg, m.state.primary_deg, 0.0005);  // 0.001° steps
    EXPECT_NEAR(g.state.secondary_deg, m.state.secondary_deg, 0.0005);
    EXPECT_NEAR(g.state.sid_mm, m.state.sid_mm, 0.005);  // 0.01 mm steps
    EXPECT_NEAR(g.state.sod_mm, m.state.sod_mm, 0.005);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(g.state.table_mm[k], m.state.table_mm[k], 0.005);
    EXPECT_EQ(g.state.fluoro_on, m.state.fluoro_on);
    EXPECT_EQ(g.state.moving, m.state.moving);
    EXPECT_EQ(g.state.zoom_mode, m.state.zoom_mode);
  }
  EXPECT_EQ(d.stats().geometry, 5u);
  EXPECT_EQ(d.stats().errors(), 0u);
}

// Version 2 added the zoom mode after the flags. An adapter speaking version 1 (geometry of
// 37 bytes) is still heard, its zoom mode 0 (not said); a version 1 geometry of version 2's
// length is not.
TEST(CArmLinkProtocol, Version1GeometryIsStillHeardWithoutAZoomMode) {
  Bytes v1;
  {
    const Bytes f = wire::encode(sample(6));
    ASSERT_TRUE(wire::cobs_decode(std::span(f).subspan(1, f.size() - 2), v1));
    v1.resize(v1.size() - 4 - 1);  // without its CRC and the zoom mode
    v1[0] = 1;
  }
  wire::Decoder d;
  const auto got = decode_all(d, raw_frame(v1));
  ASSERT_EQ(got.size(), 1u) << d.last_error();
  const auto& g = std::get<wire::GeometryMessage>(got[0]);
  EXPECT_EQ(g.state.zoom_mode, 0);
  EXPECT_NEAR(g.state.primary_deg, sample(6).state.primary_deg, 0.0005);
  EXPECT_EQ(g.state.fluoro_on, sample(6).state.fluoro_on);
  Bytes long_v1 = v1;
  long_v1.push_back(2);
  EXPECT_TRUE(decode_all(d, raw_frame(long_v1)).empty());
  EXPECT_NE(d.last_error().find("version 1 geometry body of 38 bytes (expected 37)"), std::string::npos) << d.last_error();
  // A status message is the same in both versions.
  Bytes status;
  {
    const Bytes f = wire::encode(wire::StatusMessage{8, 5, wire::StatusLevel::Warning, "collimator moving"});
    ASSERT_TRUE(wire::cobs_decode(std::span(f).subspan(1, f.size() - 2), status));
    status.resize(status.size() - 4);
    status[0] = 1;
  }
  const auto said = decode_all(d, raw_frame(status));
  ASSERT_EQ(said.size(), 1u) << d.last_error();
  EXPECT_EQ(std::get<wire::StatusMessage>(said[0]).text, "collimator moving");
}

TEST(CArmLinkProtocol, StatusRoundTrips) {
  wire::StatusMessage s{7, 123456789, wire::StatusLevel::Fault, "tube overheated"};
  wire::Decoder d;
  const auto got = decode_all(d, wire::encode(s));
  ASSERT_EQ(got.size(), 1u);
  const auto& g = std::get<wire::StatusMessage>(got[0]);
  EXPECT_EQ(g.text, "tube overheated");
  EXPECT_EQ(g.level, wire::StatusLevel::Fault);
  EXPECT_EQ(g.device_time_ns, 123456789);
  EXPECT_EQ(g.sequence, 7);
}

TEST(CArmLinkProtocol, TheSenderRefusesWhatTheWireCannotCarry) {
  auto m = sample(1);
  m.state.primary_deg = std::nan("");
  EXPECT_THROW(wire::encode(m), std::invalid_argument);
  m = sample(1);
  m.state.secondary_deg = 95;
  EXPECT_THROW(wire::encode(m), std::invalid_argument);
  m = sample(1);
  m.state.sod_mm = m.state.sid_mm + 1;
  EXPECT_THROW(wire::encode(m), std::invalid_argument);
  m = sample(1);
  m.state.sid_mm = 1000.004;  // both 100000 on the wire: the receiver would reject it
  m.state.sod_mm = 1000.0;
  EXPECT_THROW(wire::encode(m), std::invalid_argument);
  m = sample(1);
  m.state.zoom_mode = 256;
  EXPECT_THROW(wire::encode(m), std::invalid_argument);
  EXPECT_THROW(wire::encode(wire::StatusMessage{0, 0, wire::StatusLevel::Info, std::string(201, 'x')}),
               std::invalid_argument);
  EXPECT_THROW(wire::encode(wire::StatusMessage{0, 0, wire::StatusLevel::Info, "bell\a"}), std::invalid_argument);
}

TEST(CArmLinkProtocol, AnyChunkingGivesTheSameMessages) {
  Bytes stream;
  for (std::uint16_t i = 0; i < 50; ++i) append(stream, wire::encode(sample(i)));
  std::mt19937 rng(3);
  wire::Decoder d;
  std::vector<wire::Message> got;
  for (std::size_t at = 0; at < stream.size();) {
    const std::size_t n = std::min<std::size_t>(1 + rng() % 17, stream.size() - at);
    d.feed(std::span(stream).subspan(at, n), [&](const wire::Message& m) { got.push_back(m); });
    at += n;
  }
  ASSERT_EQ(got.size(), 50u);
  for (std::uint16_t i = 0; i < 50; ++i) EXPECT_EQ(std::get<wire::GeometryMessage>(got[i]).sequence, i);
  EXPECT_EQ(d.stats().bytes, stream.size());
  EXPECT_EQ(d.stats().errors(), 0u);
}

TEST(CArmLinkProtocol, GarbageBetweenMessagesCostsNoMessage) {
  std::mt19937 rng(11);
  Bytes stream;
  int garbage_chunks = 0;
  for (std::uint16_t i = 0; i < 200; ++i) {
    if (i % 3 == 0) {
      Bytes junk(1 + rng() % 40);
      for (auto& b : junk) b = static_cast<std::uint8_t>(1 + rng() % 255);  // no delimiter inside
      append(stream, junk);
      ++garbage_chunks;
    }
    append(stream, wire::encode(sample(i)));
  }
  wire::Decoder d;
  const auto got = decode_all(d, stream);
  EXPECT_EQ(got.size(), 200u);
  EXPECT_EQ(d.stats().errors(), static_cast<std::uint64_t>(garbage_chunks));
  EXPECT_EQ(d.stats().sequence.dropped, 0u);
  EXPECT_NE(d.last_error().find("frame ending at byte"), std::string::npos) << d.last_error();
}

TEST(CArmLinkProtocol, EveryBitFlipIsCaughtAndOnlyItsMessageIsLost) {
  // One flipped bit in every message of a stream, at every bit position in turn.
  const Bytes one = wire::encode(sample(1));
  ASSERT_GT(one.size(), 2u);  // two delimiters and a message between them
  for (std::size_t bit = 8; bit < (one.size() - 1) * 8; ++bit) {  // not the delimiters
    Bytes stream = wire::encode(sample(0));
    Bytes hit = wire::encode(sample(1));
    hit[bit / 8] ^= static_cast<std::uint8_t>(1u << (bit % 8));
    append(stream, hit);
    append(stream, wire::encode(sample(2)));
    wire::Decoder d;
    const auto got = decode_all(d, stream);
    ASSERT_EQ(got.size(), 2u) << "bit " << bit;
    EXPECT_EQ(std::get<wire::GeometryMessage>(got[0]).sequence, 0);
    EXPECT_EQ(std::get<wire::GeometryMessage>(got[1]).sequence, 2);
    EXPECT_GE(d.stats().crc_errors + d.stats().framing_errors, 1u);
    EXPECT_EQ(d.stats().sequence.dropped, 1u);  // the receiver knows one sample is missing
  }
}

TEST(CArmLinkProtocol, TornAndOversizedFramesAreCountedAndSkipped) {
  Bytes stream;
  const Bytes whole = wire::encode(sample(1));
  append(stream, Bytes(whole.begin(), whole.begin() + 20));  // the adapter restarted mid-frame
  append(stream, wire::encode(sample(2)));
  append(stream, Bytes(1000, 0x55));  // a runaway sender, no delimiter
  append(stream, wire::encode(sample(3)));
  wire::Decoder d;
  const auto got = decode_all(d, stream);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(d.stats().framing_errors + d.stats().crc_errors, 2u);
  EXPECT_NE(d.last_error().find("longer than 255 bytes"), std::string::npos) << d.last_error();
}

TEST(CArmLinkProtocol, WellFramedNonsenseIsRejectedByField) {
  const Bytes good_payload = [] {
    const Bytes f = wire::encode(sample(4));
    Bytes p;
    EXPECT_TRUE(wire::cobs_decode(std::span(f).subspan(1, f.size() - 2), p));
    EXPECT_GT(p.size(), 4u);
    p.resize(std::max<std::size_t>(p.size(), 4) - 4);  // without its CRC
    return p;
  }();
  struct Case {
    const char* what;
    Bytes payload;
    const char* message;
  };
  std::vector<Case> cases;
  {
    Bytes p = good_payload;
    p[0] = 3;
    cases.push_back({"version", p, "protocol version 3 (this node speaks 1 to 2)"});
  }
  {
    Bytes p = good_payload;
    p[1] = 9;
    cases.push_back({"type", p, "unknown message type 9"});
  }
  {
    Bytes p = good_payload;
    p.pop_back();
    cases.push_back({"length", p, "geometry body of 37 bytes (expected 38)"});
  }
  {
    Bytes p = good_payload;
    const std::int32_t big = 181000;  // primary angle, body offset 8
    for (int i = 0; i < 4; ++i) p[4 + 8 + i] = static_cast<std::uint8_t>(big >> (8 * i));
    cases.push_back({"angle", p, "primary angle 181000"});
  }
  {
    Bytes p = good_payload;
    p[4 + 36] = 0x80;  // flags, body offset 36
    cases.push_back({"flags", p, "reserved flag bits"});
  }
  for (const auto& c : cases) {
    wire::Decoder d;
    Bytes stream = raw_frame(c.payload);
    append(stream, wire::encode(sample(5)));
    const auto got = decode_all(d, stream);
    ASSERT_EQ(got.size(), 1u) << c.what;
    EXPECT_EQ(d.stats().errors(), 1u) << c.what;
    EXPECT_NE(d.last_error().find(c.message), std::string::npos) << c.what << ": " << d.last_error();
  }
}

TEST(CArmLinkProtocol, RandomBytesNeverCrashAndAreAllAccountedFor) {
  std::mt19937 rng(2026);
  wire::Decoder d;
  std::size_t fed = 0, delivered = 0;
  for (int round = 0; round < 200; ++round) {
    Bytes junk(1 + rng() % 5000);
    for (auto& b : junk) b = static_cast<std::uint8_t>(rng() % 8 == 0 ? 0 : rng());
    fed += junk.size();
    d.feed(junk, [&](const wire::Message&) { ++delivered; });
  }
  EXPECT_EQ(d.stats().bytes, fed);
  EXPECT_EQ(delivered, 0u);  // a 32-bit CRC lets about one random frame in 4 billion through
  EXPECT_GT(d.stats().framing_errors + d.stats().crc_errors, 1000u);
  // And the decoder still works afterwards.
  const auto got = decode_all(d, wire::encode(sample(9)));
  EXPECT_EQ(got.size(), 1u);
}
