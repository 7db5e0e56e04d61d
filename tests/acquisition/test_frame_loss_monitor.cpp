#include <gtest/gtest.h>

#include <stdexcept>

#include "evar/acquisition/frame_loss_monitor.hpp"

using namespace std::chrono_literals;
using evar::acquisition::FrameLossMonitor;
using evar::acquisition::FrameLossOptions;
using evar::acquisition::SequenceStats;

namespace {

// A source at 30 fps sampled every 250 ms: each sample adds `got` frames received and
// `lost` dropped to the running counts.
struct Feed {
  FrameLossMonitor monitor;
  FrameLossMonitor::Clock::time_point now{};
  SequenceStats counts;
  std::optional<FrameLossMonitor::Change> step(std::uint64_t got, std::uint64_t lost) {
    now += 250ms;
    counts.received += got;
    counts.dropped += lost;
    return monitor.sample(now, counts);
  }
};

}  // namespace

TEST(FrameLossMonitor, AHealthyStreamNeverRaisesIt) {
  Feed f;
  for (int i = 0; i < 400; ++i) {
    // One frame in 200 lost: 0.5 %, a link that is fine.
    EXPECT_FALSE(f.step(7, i % 25 == 0 ? 1 : 0)) << "sample " << i;
  }
  EXPECT_FALSE(f.monitor.losing());
}

TEST(FrameLossMonitor, RaisesOnceWhenAQuarterIsLostAndClearsOnceWhenTheLinkIsWhole) {
  Feed f;
  for (int i = 0; i < 20; ++i) ASSERT_FALSE(f.step(8, 0));
  // 2 of every 8 frames lost from now on: raised as soon as the window shows it.
  int raised_at = -1;
  for (int i = 0; i < 40; ++i) {
    if (auto c = f.step(6, 2)) {
      ASSERT_EQ(raised_at, -1) << "raised twice";
      raised_at = i;
      EXPECT_TRUE(c->losing);
      EXPECT_GE(c->fraction(), 0.10);
      EXPECT_LE(c->fraction(), 0.25);
      EXPECT_GE(c->expected, 10u);
      EXPECT_EQ(c->span, 2000ms) << "measured over the whole window";
    }
  }
  ASSERT_GE(raised_at, 0);
  EXPECT_LE(raised_at, 4) << "a quarter lost should be seen within a second";
  EXPECT_TRUE(f.monitor.losing());
  // The link is whole again: cleared once the whole window is clean (2 s = 8 samples).
  int cleared_at = -1;
  for (int i = 0; i < 40; ++i) {
    if (auto c = f.step(8, 0)) {
      ASSERT_EQ(cleared_at, -1) << "cleared twice";
      cleared_at = i;
      EXPECT_FALSE(c->losing);
      EXPECT_LE(c->fraction(), 0.02);
    }
  }
  EXPECT_GE(cleared_at, 7);
  EXPECT_LE(cleared_at, 8);
  EXPECT_FALSE(f.monitor.losing());
}

TEST(FrameLossMonitor, ALinkBetweenTheThresholdsDoesNotFlicker) {
  Feed f;
  for (int i = 0; i < 12; ++i) f.step(5, 3);  // heavy loss: raised
  ASSERT_TRUE(f.monitor.losing());
  // 1 of 16 lost (6 %): under the raise threshold, over the clear one. It stays raised.
  for (int i = 0; i < 200; ++i) EXPECT_FALSE(f.step(i % 2 ? 8 : 7, i % 2 ? 0 : 1)) << "sample " << i;
  EXPECT_TRUE(f.monitor.losing());
}

TEST(FrameLossMonitor, TooFewFramesToJudgeRaiseNothing) {
  Feed f;
  // 1 received, 1 lost per second: half lost, but 4 frames per window are too few.
  for (int i = 0; i < 40; ++i) EXPECT_FALSE(f.step(i % 4 == 0 ? 1 : 0, i % 4 == 0 ? 1 : 0));
  EXPECT_FALSE(f.monitor.losing());
}

TEST(FrameLossMonitor, ALinkWhoseWholeFramesComeSecondsApartDoesNotFlicker) {
  Feed f;
  for (int i = 0; i < 12; ++i) f.step(4, 4);
  ASSERT_TRUE(f.monitor.losing());
  // 99 % lost at 30 fps: a whole frame every 4 s, its predecessors' losses counted with it.
  for (int i = 0; i < 80; ++i) EXPECT_FALSE(f.step(i % 16 == 15 ? 1 : 0, i % 16 == 15 ? 119 : 0)) << "sample " << i;
  EXPECT_TRUE(f.monitor.losing());
  // Frames whole again: cleared once, after a whole clean window.
  int cleared_at = -1;
  for (int i = 0; i < 20 && cleared_at < 0; ++i) {
    if (auto c = f.step(8, 0)) {
      cleared_at = i;
      EXPECT_FALSE(c->losing);
      EXPECT_EQ(c->lost, 0u);
    }
  }
  EXPECT_EQ(cleared_at, 7);
}

TEST(FrameLossMonitor, CountsThatGoBackwardsStartAFreshHistory) {
  Feed f;
  for (int i = 0; i < 12; ++i) f.step(100, 1);  // 1 % lost: no alarm
  ASSERT_FALSE(f.monitor.losing());
  // A source restarted from zero: the difference is not taken as billions of frames.
  f.counts = {};
  EXPECT_FALSE(f.step(8, 0));
  for (int i = 0; i < 12; ++i) EXPECT_FALSE(f.step(8, 0));
}

TEST(FrameLossMonitor, RefusesOptionsThatCannotWork) {
  EXPECT_THROW(FrameLossMonitor(FrameLossOptions{.window = 0ms}), std::invalid_argument);
  EXPECT_THROW(FrameLossMonitor(FrameLossOptions{.raise_fraction = 0.1, .clear_fraction = 0.1}), std::invalid_argument);
  EXPECT_THROW(FrameLossMonitor(FrameLossOptions{.raise_fraction = 1.5}), std::invalid_argument);
}
