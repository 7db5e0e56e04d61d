#include <gtest/gtest.h>

#include <string>

#include "evar/acquisition/frame.hpp"
#include "evar/acquisition/stream_state.hpp"

using namespace evar::acquisition;

TEST(StreamState, OnlyAStreamingSourceMayBeShownAsLive) {
  EXPECT_TRUE(is_live(StreamState::Streaming));
  for (auto s : {StreamState::Stopped, StreamState::Connecting, StreamState::Stalled, StreamState::Disconnected})
    EXPECT_FALSE(is_live(s)) << to_string(s);
  EXPECT_EQ(std::string(to_string(StreamState::Stalled)), "stalled");
}

TEST(PixelFormat, TwelveAndSixteenBitFramesUseTwoBytesPerPixel) {
  EXPECT_EQ(bytes_per_pixel(PixelFormat::Mono8), 1);
  EXPECT_EQ(bytes_per_pixel(PixelFormat::Mono12), 2);
  EXPECT_EQ(bytes_per_pixel(PixelFormat::Mono16), 2);
  EXPECT_EQ(std::string(to_string(PixelFormat::Mono12)), "Mono12");
}
