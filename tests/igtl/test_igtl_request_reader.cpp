// The server's reading of what clients send, below the socket: message framing, pushed
// bodies read past without being kept, and the garbage verdict.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "igtl_request_reader.hpp"

using evar::overlay::IgtlMessageHeader;
using evar::overlay::IgtlRequestReader;

namespace {

std::vector<std::uint8_t> header(const std::string& type, const std::string& device, std::uint64_t body) {
  std::vector<std::uint8_t> h(IgtlRequestReader::kHeaderBytes, 0);
  h[1] = 2;  // version 2, big-endian
  for (std::size_t i = 0; i < type.size() && i < 12; ++i) h[2 + i] = static_cast<std::uint8_t>(type[i]);
  for (std::size_t i = 0; i < device.size() && i < 20; ++i) h[14 + i] = static_cast<std::uint8_t>(device[i]);
  for (int i = 0; i < 8; ++i) h[42 + i] = static_cast<std::uint8_t>(body >> (56 - 8 * i));
  return h;
}

void append(std::vector<std::uint8_t>& to, const std::vector<std::uint8_t>& more) {
  to.insert(to.end(), more.begin(), more.end());
}

}  // namespace

TEST(IgtlRequestReader, RequestsSentOneByteAtATimeAreReadWholeAndInOrder) {
  std::vector<std::uint8_t> stream;
  append(stream, header("GET_IMAGE", "Client", 0));
  append(stream, header("GET_POLYDATA", "aorta", 0));
  append(stream, header("GET_STATUS", "a-device-name-of-20c", 0));
  IgtlRequestReader reader;
  std::vector<IgtlMessageHeader> got;
  for (std::uint8_t b : stream) ASSERT_TRUE(reader.feed(&b, 1, got));
  ASSERT_EQ(got.size(), 3u);
  EXPECT_EQ(got[0].type, "GET_IMAGE");
  EXPECT_EQ(got[0].device, "Client");
  EXPECT_EQ(got[1].type, "GET_POLYDATA");
  EXPECT_EQ(got[1].device, "aorta");
  EXPECT_EQ(got[2].device, "a-device-name-of-20c");
  EXPECT_TRUE(got[2].request());
  EXPECT_EQ(reader.buffered(), 0u);
}

TEST(IgtlRequestReader, APushedBodyIsReadPastWithoutBeingKept) {
  IgtlRequestReader reader;
  std::vector<IgtlMessageHeader> got;
  const std::uint64_t body = 3u << 20;  // a 3 MiB IMAGE pushed at the node
  const auto h = header("IMAGE", "Probe", body);
  ASSERT_TRUE(reader.feed(h.data(), h.size(), got));
  ASSERT_EQ(got.size(), 1u);
  EXPECT_FALSE(got[0].request());
  EXPECT_EQ(got[0].body_bytes, body);
  const std::vector<std::uint8_t> chunk(64 * 1024, 0xAB);
  for (std::uint64_t sent = 0; sent < body; sent += chunk.size()) {
    ASSERT_TRUE(reader.feed(chunk.data(), chunk.size(), got));
    EXPECT_EQ(reader.buffered(), 0u) << "after " << sent << " bytes of the body";
  }
  // Then a request, read as one.
  const auto get = header("GET_STATUS", "", 0);
  ASSERT_TRUE(reader.feed(get.data(), get.size(), got));
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[1].type, "GET_STATUS");
}

TEST(IgtlRequestReader, ARequestAnnouncingAHugeBodyIsGarbageAndNothingMoreIsRead) {
  IgtlRequestReader reader;
  std::vector<IgtlMessageHeader> got;
  std::vector<std::uint8_t> stream = header("GET_STATUS", "Client", 0);
  append(stream, header("GET_IMAGE", "Client", std::uint64_t{1} << 40));
  append(stream, header("GET_STATUS", "Client", 0));
  EXPECT_FALSE(reader.feed(stream.data(), stream.size(), got));
  EXPECT_TRUE(reader.garbage());
  ASSERT_EQ(got.size(), 1u) << "the request before the garbage is still answered";
  EXPECT_EQ(reader.buffered(), 0u);
  EXPECT_FALSE(reader.feed(stream.data(), stream.size(), got));
  EXPECT_EQ(got.size(), 1u);
}

TEST(IgtlRequestReader, ARequestWithASmallBodyWaitsForItWhole) {
  IgtlRequestReader reader;
  std::vector<IgtlMessageHeader> got;
  std::vector<std::uint8_t> stream = header("GET_STATUS", "Client", 4);
  append(stream, {1, 2, 3, 4});
  ASSERT_TRUE(reader.feed(stream.data(), stream.size() - 1, got));
  EXPECT_TRUE(got.empty());
  EXPECT_EQ(reader.buffered(), stream.size() - 1);
  ASSERT_TRUE(reader.feed(stream.data() + stream.size() - 1, 1, got));
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(reader.buffered(), 0u);
}
