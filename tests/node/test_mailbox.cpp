// The hand-over points between the node's threads: what they drop is counted, what is
// left at shutdown is neither delivered nor lost from the counts.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "mailbox.hpp"

using evar::node::BoundedQueue;
using evar::node::LatestSlot;
using namespace std::chrono_literals;

TEST(BoundedQueue, DropsItsOldestWhenFullAndHandsOutWhatIsLeftAfterClosing) {
  BoundedQueue<int> q(2);
  EXPECT_FALSE(q.push(1));
  EXPECT_FALSE(q.push(2));
  EXPECT_TRUE(q.push(3));  // 1 dropped
  EXPECT_EQ(q.dropped(), 1u);
  q.close();
  EXPECT_FALSE(q.push(4)) << "nothing is added once closed";
  EXPECT_FALSE(q.closed()) << "closed, but items are left";
  EXPECT_EQ(q.pop(0ms), 2);
  EXPECT_EQ(q.pop(0ms), 3);
  EXPECT_FALSE(q.pop(0ms));
  EXPECT_TRUE(q.closed());
}

TEST(BoundedQueue, APushThatWaitsForRoomIsReleasedByClose) {
  BoundedQueue<int> q(1);
  ASSERT_TRUE(q.push_wait(1));
  std::thread producer([&] { EXPECT_FALSE(q.push_wait(2)); });
  std::this_thread::sleep_for(20ms);
  q.close();
  producer.join();
  EXPECT_EQ(q.pop(0ms), 1);
  EXPECT_FALSE(q.pop(0ms));
}

TEST(LatestSlot, KeepsTheNewestAndCountsWhatWasNeverTakenAlsoAtClose) {
  LatestSlot<int> slot;
  EXPECT_FALSE(slot.put(1));
  EXPECT_TRUE(slot.put(2));  // 1 superseded
  EXPECT_EQ(slot.take(), 2);
  EXPECT_FALSE(slot.try_take());
  EXPECT_FALSE(slot.put(3));
  slot.close();  // 3 left untaken: counted, not delivered
  EXPECT_EQ(slot.superseded(), 2u);
  EXPECT_FALSE(slot.take());
  EXPECT_FALSE(slot.put(4)) << "nothing is added once closed";
  EXPECT_EQ(slot.superseded(), 2u);
}

// An item put only when none waits never replaces a newer one (the pair on screen adapted
// again after the pelvis moved the models must not push out a new view's pair).
TEST(LatestSlot, PutIfEmptyNeverReplacesWhatWaits) {
  LatestSlot<int> slot;
  EXPECT_TRUE(slot.put_if_empty(1));
  EXPECT_FALSE(slot.put_if_empty(2));
  EXPECT_EQ(slot.try_take(), 1);
  EXPECT_EQ(slot.superseded(), 0u);
  EXPECT_TRUE(slot.put_if_empty(3));
  slot.put(4);  // a newer item still replaces it
  EXPECT_EQ(slot.superseded(), 1u);
  EXPECT_EQ(slot.try_take(), 4);
  slot.close();
  EXPECT_FALSE(slot.put_if_empty(5));
  EXPECT_EQ(slot.try_take(), std::nullopt);
}

TEST(LatestSlot, ATakeThatWaitsIsReleasedByClose) {
  LatestSlot<int> slot;
  std::thread consumer([&] { EXPECT_FALSE(slot.take()); });
  std::this_thread::sleep_for(20ms);
  slot.close();
  consumer.join();
}
