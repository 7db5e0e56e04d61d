#include <gtest/gtest.h>

#include <string>

#include "evar/acquisition/stream_state.hpp"

using namespace evar::acquisition;

TEST(StreamState, OnlyAStreamingSourceMayBeShownAsLive) {
  EXPECT_TRUE(is_live(StreamState::Streaming));
  for (auto s : {StreamState::Stopped, StreamState::Connecting, StreamState::Stalled, StreamState::Disconnected})
    EXPECT_FALSE(is_live(s)) << to_string(s);
  EXPECT_EQ(std::string(to_string(StreamState::Stalled)), "stalled");
}
