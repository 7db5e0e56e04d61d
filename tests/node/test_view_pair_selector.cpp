// Which frames the device is reconstructed from: views, pairs, failed partners, restarts.
#include <gtest/gtest.h>

#include "evar/node/frame_view.hpp"
#include "evar/node/view_pair_selector.hpp"

namespace {

using namespace evar;

// A view-pair candidate at these angles (degrees) and time (s) on a 256 px detector.
node::ViewCandidate view_candidate(std::uint64_t frame, double primary, double secondary = 0.0, double t_s = 0.0) {
  acquisition::CArmState s;
  s.primary_deg = primary;
  s.secondary_deg = secondary;
  s.sid_mm = 1200;
  s.sod_mm = 800;
  node::ViewCandidate c;
  c.frame = frame;
  c.time_ns = static_cast<std::int64_t>(t_s * 1e9);
  c.geometry = node::frame_view(geometry::DetectorSpec{256, 256, 1.0, 1.0}, Eigen::Matrix4d::Identity(), s);
  return c;
}

TEST(ViewPairSelector, PairsTheFirstCandidateOfANewViewWithAFarEnoughEarlierView) {
  const auto candidate = [](std::uint64_t frame, double primary, double secondary) {
    return view_candidate(frame, primary, secondary);
  };
  node::ViewPairSelector selector(20.0);
  EXPECT_FALSE(selector.add(candidate(1, 0, 0)));
  EXPECT_FALSE(selector.add(candidate(2, 0.5, 0)));   // the same view
  EXPECT_FALSE(selector.add(candidate(3, 10, 0)));    // another view, too close to AP
  const auto pair = selector.add(candidate(4, 40, 0));
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->later.frame, 4u);
  EXPECT_EQ(pair->earlier.frame, 3u);                 // the newest view far enough (30°)
  EXPECT_NEAR(pair->separation_deg, 30.0, 0.5);
  EXPECT_FALSE(selector.add(candidate(5, 40, 0)));    // still the same view: no new pair
  selector.failed(pair->earlier.id());  // the pair failed
  const auto again = selector.add(candidate(6, 40, 0));
  ASSERT_TRUE(again);
  EXPECT_EQ(again->later.frame, 6u);
  EXPECT_THROW(node::ViewPairSelector(10.0, {20.0, 8}), std::invalid_argument);
}

// A pair that keeps failing with the same partner frame (a false segmentation there) is
// not retried with it for ever: after two failures in a row the partner is forgotten and
// the next older view far enough pairs instead (before the fix every frame of the
// current view failed against the same partner until the C-arm moved).
TEST(ViewPairSelector, APartnerThatKeepsFailingIsForgottenForAnOlderView) {
  const auto candidate = [](std::uint64_t frame, double primary) { return view_candidate(frame, primary); };
  node::ViewPairSelector selector(20.0);
  EXPECT_FALSE(selector.add(candidate(1, 0)));    // AP
  EXPECT_FALSE(selector.add(candidate(2, -10)));  // too close to AP
  auto pair = selector.add(candidate(3, 30));     // LAO 30: the newest view far enough is frame 2 (40°)
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->earlier.frame, 2u);
  selector.failed(pair->earlier.id());
  pair = selector.add(candidate(4, 30));          // a newer frame, the same partner
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->earlier.frame, 2u);
  selector.failed(pair->earlier.id());  // failed again with frame 2: it goes
  pair = selector.add(candidate(5, 30));
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->earlier.frame, 1u);             // AP, 30° away
  selector.failed(pair->earlier.id());
  pair = selector.add(candidate(6, 30));
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->earlier.frame, 1u);
  selector.failed(pair->earlier.id());  // AP fails twice too: nothing left to pair with
  EXPECT_FALSE(selector.add(candidate(7, 30)));
  // The C-arm goes back to a view: a new candidate there pairs again.
  pair = selector.add(candidate(8, -10));
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->earlier.frame, 7u);
  EXPECT_THROW(node::ViewPairSelector(20.0, {2.0, 8, 120'000'000'000, 0}), std::invalid_argument);
}

// Failures count against the pair's own partner and only in a row: a success in between
// clears them (an independent review found both wrong in the first version).
TEST(ViewPairSelector, OnlyFailuresInARowWithThePairsOwnPartnerCount) {
  node::ViewPairSelector selector(20.0);
  EXPECT_FALSE(selector.add(view_candidate(1, 0)));
  auto pair = selector.add(view_candidate(2, 30));
  ASSERT_TRUE(pair);
  selector.failed(pair->earlier.id());
  pair = selector.add(view_candidate(3, 30));     // tried again with the newer frame
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->earlier.frame, 1u);
  selector.succeeded(pair->earlier.id());  // and it worked: the failure before is forgotten
  EXPECT_FALSE(selector.add(view_candidate(4, 30)));
  pair = selector.add(view_candidate(5, 35));     // a new view, 5° on: AP is its partner again
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->earlier.frame, 1u);
  selector.failed(pair->earlier.id());  // one failure since the success: AP stays
  pair = selector.add(view_candidate(6, 35));
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->earlier.frame, 1u);
}

// A source that reconnects (a camera restarted, a grabber plugged back) numbers its frames
// from the start again: a frame number seen before is another frame. Forgetting a partner
// that kept failing forgets that frame only, not an older view that had the same number
// (before the fix both went, and with them the only view left to pair with).
TEST(ViewPairSelector, AFrameNumberUsedAgainAfterAReconnectIsAnotherFrame) {
  node::ViewPairSelector selector(20.0);
  EXPECT_FALSE(selector.add(view_candidate(5, 0, 0.0, 1.0)));  // AP, frame 5
  // The camera reconnects and numbers from 1 again; its frame 5 is RAO 30.
  auto pair = selector.add(view_candidate(5, -30, 0.0, 20.0));
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->earlier.time_ns, 1'000'000'000);  // AP
  selector.succeeded(pair->earlier.id());
  // LAO 30 pairs with RAO 30 (60° apart), which fails twice: RAO's frame 5 is forgotten.
  for (std::uint64_t frame : {9, 10}) {
    pair = selector.add(view_candidate(frame, 30, 0.0, 30.0 + static_cast<double>(frame)));
    ASSERT_TRUE(pair);
    EXPECT_EQ(pair->earlier.frame, 5u);
    EXPECT_EQ(pair->earlier.time_ns, 20'000'000'000) << "RAO";
    selector.failed(pair->earlier.id());
  }
  // AP's frame 5 is another frame: it stays, and pairs with the current view.
  pair = selector.add(view_candidate(11, 30, 0.0, 41.0));
  ASSERT_TRUE(pair) << "the AP view went with the failed frame of the same number";
  EXPECT_EQ(pair->earlier.time_ns, 1'000'000'000);
  EXPECT_NEAR(pair->separation_deg, 30.0, 0.5);
}

TEST(ViewPairSelector, AViewOlderThanTheGapOrFromBeforeATimeRestartIsNotPaired) {
  const auto candidate = [](std::uint64_t frame, double primary, double t_s) { return view_candidate(frame, primary, 0.0, t_s); };
  node::ViewPairOptions o;
  o.max_gap_ns = 60'000'000'000;
  node::ViewPairSelector selector(20.0, o);
  EXPECT_FALSE(selector.add(candidate(1, 0, 100.0)));
  EXPECT_FALSE(selector.add(candidate(2, 40, 161.0)));  // 61 s later: the device may have moved
  const auto pair = selector.add(candidate(3, 0, 200.0));  // 39 s after view 2
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->earlier.frame, 2u);
  // Time went back (a clock or a replay that started over): what came before is forgotten.
  EXPECT_FALSE(selector.add(candidate(4, 40, 5.0)));
  const auto fresh = selector.add(candidate(5, 0, 6.0));
  ASSERT_TRUE(fresh);
  EXPECT_EQ(fresh->earlier.frame, 4u);
  o.max_gap_ns = 0;
  EXPECT_THROW(node::ViewPairSelector(20.0, o), std::invalid_argument);
}

}  // namespace
