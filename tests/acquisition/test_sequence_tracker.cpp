#include <gtest/gtest.h>

#include "evar/acquisition/sequence_tracker.hpp"

using evar::acquisition::SequenceTracker;

TEST(SequenceTracker, CountsForwardGapsAsDrops) {
  SequenceTracker t;
  for (std::uint64_t s : {10u, 11u, 12u}) EXPECT_EQ(t.observe(s), 0u);
  EXPECT_EQ(t.observe(15), 2u);  // 13 and 14 lost
  EXPECT_EQ(t.stats().received, 4u);
  EXPECT_EQ(t.stats().dropped, 2u);
}

TEST(SequenceTracker, WrapsAroundTheCounterWidth) {
  SequenceTracker t(16);  // GigE Vision 1.x block ids are 16 bit
  t.observe(65534);
  EXPECT_EQ(t.observe(65535), 0u);
  EXPECT_EQ(t.observe(0), 0u);
  EXPECT_EQ(t.observe(2), 1u);
  EXPECT_EQ(t.stats().dropped, 1u);
}

TEST(SequenceTracker, TellsDuplicatesReorderingAndRestartsApart) {
  SequenceTracker t(32, 8);
  t.observe(5000);
  t.observe(5000);
  t.observe(4998);  // late frame
  t.observe(3);     // camera restarted its counter
  EXPECT_EQ(t.observe(4), 0u);
  EXPECT_EQ(t.stats().duplicates, 1u);
  EXPECT_EQ(t.stats().out_of_order, 1u);
  EXPECT_EQ(t.stats().restarts, 1u);
  EXPECT_EQ(t.stats().dropped, 0u);
}

TEST(SequenceTracker, RefusesAnImpossibleCounterWidth) {
  EXPECT_THROW(SequenceTracker(1), std::invalid_argument);
  EXPECT_THROW(SequenceTracker(65), std::invalid_argument);
}
