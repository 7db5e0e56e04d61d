#include <gtest/gtest.h>

#include <limits>
#include <random>

#include "evar/acquisition/clock_offset.hpp"
#include "evar/acquisition/geometry_timeline.hpp"

namespace acq = evar::acquisition;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

namespace {

// A C-arm whose clock runs 5 s behind the host's, sampled at 10 Hz, each sample arriving
// 1–21 ms late over the serial link; it turns at 20°/s between 1 s and 2 s.
struct Scenario {
  Clock::time_point t0 = Clock::time_point(100s);
  static constexpr std::int64_t kCarmBehindNs = 5'000'000'000;
  static double primary_at(double s) { return s < 1.0 ? 0.0 : s < 2.0 ? 20.0 * (s - 1.0) : 20.0; }
  std::vector<acq::CArmState> samples(double until_s) const {
    std::mt19937 rng(9);
    std::uniform_int_distribution<int> delay_ms(1, 21);
    std::vector<acq::CArmState> out;
    for (double s = 0.0; s <= until_s + 1e-9; s += 0.1) {
      acq::CArmState c;
      const auto host = t0 + std::chrono::nanoseconds(static_cast<std::int64_t>(s * 1e9));
      c.device_time_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(host.time_since_epoch()).count() - kCarmBehindNs;
      c.host_arrival = host + std::chrono::milliseconds(delay_ms(rng));
      c.primary_deg = primary_at(s);
      c.secondary_deg = -10.0;
      c.sid_mm = 1200;
      c.sod_mm = 800;
      c.moving = s > 1.0 - 1e-9 && s < 2.0 + 1e-9;
      out.push_back(c);
    }
    return out;
  }
  Clock::time_point at(double s) const { return t0 + std::chrono::nanoseconds(static_cast<std::int64_t>(s * 1e9)); }
};

}  // namespace

TEST(ClockOffsetEstimator, TakesTheSmallestDelayAsTheOffset) {
  acq::ClockOffsetEstimator e(8);
  EXPECT_FALSE(e.offset_ns());
  for (std::int64_t d : {7, 3, 9, 12, 4}) e.add(1000, 1000 + 500 + d);
  EXPECT_EQ(*e.offset_ns(), 503);
  EXPECT_EQ(*e.typical_delay_ns(), 4);  // median of the delays above the minimum: 0 1 4 6 9
  EXPECT_EQ(e.to_host_ns(2000), 2503);
  EXPECT_THROW(acq::ClockOffsetEstimator(0), std::invalid_argument);
}

TEST(GeometryTimeline, InterpolatesTheGeometryAtAFramesTimeDespiteLinkJitter) {
  Scenario sc;
  acq::GeometryTimeline tl;
  for (const auto& s : sc.samples(3.0)) tl.add(s);
  // The offset is the clock difference plus the smallest delay seen (1 ms here).
  ASSERT_TRUE(tl.carm_clock_offset_ns());
  EXPECT_NEAR(static_cast<double>(*tl.carm_clock_offset_ns()), 5.001e9, 1e6);
  for (double s : {1.25, 1.5, 1.73}) {
    const auto g = tl.at(sc.at(s));
    ASSERT_TRUE(g);
    // Linear motion, so interpolation is exact up to the 1 ms of placement error (0.02°).
    EXPECT_NEAR(g->state.primary_deg, Scenario::primary_at(s), 0.03) << s;
    EXPECT_TRUE(g->moving) << s;
    EXPECT_FALSE(g->stale) << s;
  }
  const auto settled = tl.at(sc.at(2.55));
  EXPECT_NEAR(settled->state.primary_deg, 20.0, 1e-9);
  EXPECT_FALSE(settled->moving);
  EXPECT_FALSE(settled->stale);
  EXPECT_LE(settled->age_ns, 51'000'000);
}

// A replay faster than recorded: samples arrive on the host ten times faster than their
// C-arm times go on, so the host-to-C-arm offset fits no part of the history. A frame
// stamped on the C-arm's clock (a session's frames) is looked up there and gets its own
// geometry exactly; through the host time it would get another.
TEST(GeometryTimeline, AFrameOnTheCArmsClockGetsItsGeometryWhateverTheHostsRate) {
  Scenario sc;
  acq::GeometryTimeline tl;
  auto samples = sc.samples(3.0);
  const auto first = samples.front().device_time_ns;
  for (auto& c : samples) c.host_arrival = sc.t0 + std::chrono::nanoseconds((c.device_time_ns - first) / 10);
  for (const auto& c : samples) tl.add(c);
  for (double s : {0.5, 1.5, 2.55}) {
    const auto g = tl.at_carm_time(first + static_cast<std::int64_t>(s * 1e9));
    ASSERT_TRUE(g);
    EXPECT_NEAR(g->state.primary_deg, Scenario::primary_at(s), 1e-9) << s;
    EXPECT_EQ(g->moving, s > 1.0 && s < 2.1) << s;
    EXPECT_FALSE(g->stale) << s;
  }
  // The frame at 0.5 s by its host arrival (a tenth of the way in host time) is placed
  // after the turn.
  const auto by_host = tl.at(sc.t0 + std::chrono::nanoseconds(50'000'000));
  ASSERT_TRUE(by_host);
  EXPECT_GT(std::abs(by_host->state.primary_deg - Scenario::primary_at(0.5)), 5.0);
}

TEST(GeometryTimeline, AFrameAfterTheLinkWentSilentHasStaleGeometry) {
  Scenario sc;
  acq::GeometryTimeline tl;
  for (const auto& s : sc.samples(0.5)) tl.add(s);
  EXPECT_FALSE(tl.at(sc.at(0.6))->stale);   // 100 ms after the last sample
  const auto late = tl.at(sc.at(1.5));      // a second after it
  EXPECT_TRUE(late->stale);
  EXPECT_NEAR(late->age_ns, 1.0e9, 2e7);
  EXPECT_FALSE(acq::GeometryTimeline().at(sc.at(1.0)));  // no geometry at all: nothing to pair
}

TEST(GeometryTimeline, ARestartedCArmClockStartsAFreshHistory) {
  Scenario sc;
  acq::GeometryTimeline tl;
  for (const auto& s : sc.samples(1.0)) tl.add(s);
  const std::size_t kept = tl.size();
  acq::CArmState restarted = sc.samples(0.0)[0];
  restarted.device_time_ns = 42;  // the C-arm rebooted
  restarted.host_arrival = sc.at(1.2);
  restarted.primary_deg = 30.0;
  tl.add(restarted);
  EXPECT_EQ(tl.size(), kept) << "one far-behind sample alone could be a stray";
  EXPECT_EQ(tl.restarts(), 0u);
  restarted.device_time_ns += 100'000'000;  // the next, 100 ms on: a restart
  restarted.host_arrival = sc.at(1.3);
  tl.add(restarted);
  EXPECT_EQ(tl.size(), 2u);
  EXPECT_EQ(tl.restarts(), 1u);
  EXPECT_EQ(tl.dropped_samples(), 0u);
  EXPECT_NEAR(tl.at(sc.at(1.25))->state.primary_deg, 30.0, 1e-9);
}

// One sample with a stray time far in the past (a C-arm interface's glitch that passed the
// CRC): dropped once the next sample goes on from the real clock, and the history and the
// clock offset stay as they were.
TEST(GeometryTimeline, AStrayFarBehindSampleIsDroppedNotTakenForARestart) {
  Scenario sc;
  acq::GeometryTimeline tl;
  const auto samples = sc.samples(3.0);
  acq::GeometryTimeline clean;  // the same samples without the stray
  for (const auto& s : samples) clean.add(s);
  for (std::size_t i = 0; i + 1 < samples.size(); ++i) tl.add(samples[i]);
  acq::CArmState stray = samples.back();
  stray.device_time_ns -= 3'600'000'000'000;  // an hour in the past
  stray.primary_deg = 99.0;
  tl.add(stray);
  tl.add(samples.back());
  EXPECT_EQ(tl.restarts(), 0u);
  EXPECT_EQ(tl.dropped_samples(), 1u);
  EXPECT_EQ(tl.size(), clean.size());
  EXPECT_EQ(tl.carm_clock_offset_ns(), clean.carm_clock_offset_ns());
  EXPECT_NEAR(tl.at(sc.at(3.0))->state.primary_deg, 20.0, 1e-9);
}

TEST(GeometryTimeline, ALateRepeatedOrAbsurdSampleIsDroppedNotTakenForARestart) {
  Scenario sc;
  acq::GeometryTimeline tl;
  const auto samples = sc.samples(3.0);
  for (const auto& s : samples) tl.add(s);
  const std::size_t kept = tl.size();
  const double before = tl.at(sc.at(2.95))->state.primary_deg;
  acq::CArmState late = samples[samples.size() - 3];  // 0.2 s behind the newest, arriving now
  late.host_arrival = sc.at(3.05);
  late.primary_deg = 99.0;
  tl.add(late);
  tl.add(samples.back());  // a repeat
  acq::CArmState absurd = samples.back();  // a device time at the far end of int64 (garbage that passed the CRC)
  absurd.device_time_ns = std::numeric_limits<std::int64_t>::min();
  tl.add(absurd);  // dropped, no overflow (UBSan would stop here), not a restart
  absurd.device_time_ns = std::numeric_limits<std::int64_t>::max();
  tl.add(absurd);
  EXPECT_EQ(tl.size(), kept);
  EXPECT_EQ(tl.dropped_samples(), 4u);
  EXPECT_EQ(tl.restarts(), 0u);
  EXPECT_DOUBLE_EQ(tl.at(sc.at(2.95))->state.primary_deg, before);
  EXPECT_FALSE(tl.at(sc.at(2.95))->stale);
}

// A stray time ahead of the clock (garbage that passed the CRC, an hour or 0.6 s ahead):
// before the fix it was taken at once, served as the newest geometry, spoiled the clock
// offset by its lead and made the real samples after it look late, so they were dropped
// and every frame for the next 25 s was stale. Now it is held, and dropped when the next
// sample goes on from the real clock.
TEST(GeometryTimeline, AStrayAheadSampleIsNeverServedAndSpoilsNothing) {
  for (const std::int64_t lead_ns : {std::int64_t{3'600'000'000'000}, std::int64_t{600'000'000}}) {
    Scenario sc;
    const auto samples = sc.samples(4.0);
    acq::GeometryTimeline tl, clean;
    for (const auto& s : samples) clean.add(s);
    std::size_t i = 0;
    for (; i < 31; ++i) tl.add(samples[i]);  // up to 3.0 s
    acq::CArmState stray = samples[i];
    stray.device_time_ns += lead_ns;
    stray.primary_deg = -90.0;
    tl.add(stray);
    const auto meanwhile = tl.at(sc.at(3.05));
    ASSERT_TRUE(meanwhile);
    EXPECT_NEAR(meanwhile->state.primary_deg, 20.0, 1e-9) << lead_ns;
    for (; i < samples.size(); ++i) tl.add(samples[i]);
    EXPECT_EQ(tl.restarts(), 0u) << lead_ns;
    EXPECT_EQ(tl.dropped_samples(), 1u) << lead_ns;  // the stray only: no real sample lost
    EXPECT_EQ(tl.size(), clean.size()) << lead_ns;
    EXPECT_EQ(tl.carm_clock_offset_ns(), clean.carm_clock_offset_ns()) << lead_ns;
    const auto later = tl.at(sc.at(3.55));
    EXPECT_FALSE(later->stale) << lead_ns;
    EXPECT_NEAR(later->state.primary_deg, 20.0, 1e-9) << lead_ns;
  }
}

// A C-arm whose clock is set forward (an hour) goes on from the new time: the second sample
// confirms it, and frames are timed by the new clock at once.
TEST(GeometryTimeline, AClockSetForwardStartsAFreshHistory) {
  Scenario sc;
  acq::GeometryTimeline tl;
  for (const auto& s : sc.samples(1.0)) tl.add(s);
  auto later = sc.samples(3.0);
  for (std::size_t i = 12; i < later.size(); ++i) {  // from 1.2 s on: the clock an hour ahead
    later[i].device_time_ns += 3'600'000'000'000;
    tl.add(later[i]);
  }
  EXPECT_EQ(tl.restarts(), 1u);
  EXPECT_EQ(tl.dropped_samples(), 0u);
  for (double s : {1.55, 1.85}) {
    const auto g = tl.at(sc.at(s));
    EXPECT_FALSE(g->stale) << s;
    EXPECT_NEAR(g->state.primary_deg, Scenario::primary_at(s), 0.03) << s;
  }
}

// After a reboot, a C-arm that sends only every 1.5 s (slower than the protocol asks, as
// older recordings do) is still recognised: the second sample goes on from the first as
// far as the host's clock did (before the fix it had to come within 1 s).
TEST(GeometryTimeline, ASlowSenderRestartIsConfirmedAndTimedByItsNewClock) {
  Scenario sc;
  acq::GeometryTimeline tl;
  for (const auto& s : sc.samples(1.0)) tl.add(s);
  for (int k = 0; k < 4; ++k) {
    acq::CArmState c = sc.samples(0.0)[0];
    c.device_time_ns = 1'000 + k * 1'500'000'000LL;  // rebooted: its clock starts near 0
    c.host_arrival = sc.at(1.5 + 1.5 * k) + 3ms;
    c.primary_deg = 30.0 + k;  // turning slowly
    tl.add(c);
  }
  EXPECT_EQ(tl.restarts(), 1u);
  EXPECT_EQ(tl.dropped_samples(), 0u);
  // Half-way between the third and fourth samples (host 5.25 s): 32.5°.
  EXPECT_NEAR(tl.at(sc.at(5.25))->state.primary_deg, 32.5, 0.01);
}

// The primary angle's ends meet: 180° and −180° are one position, and a turn through it is
// 4°, not 356°.
TEST(GeometryTimeline, ThePrimaryAngleIsInterpolatedTheShortWayRound) {
  Scenario sc;
  acq::GeometryTimeline tl;
  auto samples = sc.samples(2.0);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    samples[i].moving = false;
    samples[i].primary_deg = i < 10 ? (i % 2 ? 180.0 : -180.0) : (i == 10 ? 178.0 : -178.0);
    tl.add(samples[i]);
  }
  const auto parked = tl.at(sc.at(0.55));
  EXPECT_NEAR(std::abs(parked->state.primary_deg), 180.0, 1e-9);
  EXPECT_FALSE(parked->moving);
  // Between 178° (1.0 s) and −178° (1.1 s).
  EXPECT_NEAR(tl.at(sc.at(1.025))->state.primary_deg, 179.0, 0.05);
  EXPECT_NEAR(tl.at(sc.at(1.075))->state.primary_deg, -179.0, 0.05);
  EXPECT_TRUE(tl.at(sc.at(1.05))->moving);
}

// A table pan moves the image as a turn does: frames during it are marked moving even
// when the C-arm does not set its flag.
// A table pan, a detector move or a zoom change moves the image as a turn does.
TEST(GeometryTimeline, ATablePanOrDetectorMoveIsMovement) {
  Scenario sc;
  auto samples = sc.samples(3.0);
  for (auto& s : samples) s.moving = false;
  acq::GeometryTimeline tl;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    samples[i].primary_deg = 20.0;
    if (i == 26) samples[i].table_mm[2] = 10.0;  // the table moves 10 mm between 2.5 and 2.6 s
    if (i > 26) samples[i].table_mm[2] = 10.0;
    if (i > 28) samples[i].sid_mm = 1100.0;      // and the detector comes down between 2.8 and 2.9 s
    samples[i].zoom_mode = i > 23 ? 2 : 1;       // and the zoom changes between 2.3 and 2.4 s
    tl.add(samples[i]);
  }
  EXPECT_FALSE(tl.at(sc.at(2.25))->moving);
  EXPECT_TRUE(tl.at(sc.at(2.35))->moving);
  EXPECT_EQ(tl.at(sc.at(2.45))->state.zoom_mode, 2);
  EXPECT_FALSE(tl.at(sc.at(2.45))->moving);
  EXPECT_TRUE(tl.at(sc.at(2.55))->moving);
  EXPECT_FALSE(tl.at(sc.at(2.65))->moving);
  EXPECT_TRUE(tl.at(sc.at(2.85))->moving);
  EXPECT_FALSE(tl.at(sc.at(2.95))->moving);
}

// A session that sends only every 1.5 s, replayed four times faster than recorded: each
// sample arrives 1.1 s before its time by the offset so far. With the limit `run --replay`
// sets (the longest gap plus 250 ms) none is held or lost; with the live default every one
// after the first would be taken for a stray (an independent review's finding).
TEST(GeometryTimeline, AFastReplayOfASparseSessionKeepsEverySample) {
  const auto feed = [](acq::GeometryTimeline& tl) {
    for (int k = 0; k < 10; ++k) {
      acq::CArmState c;
      c.device_time_ns = 1'000'000'000LL + k * 1'500'000'000LL;
      c.host_arrival = Clock::time_point(100s) + std::chrono::milliseconds(375 * k);
      c.primary_deg = 10.0 * k;
      c.sid_mm = 1200;
      c.sod_mm = 800;
      tl.add(c);
    }
  };
  acq::GeometryTimelineOptions replay;
  replay.ahead_after = std::chrono::milliseconds(1'500 + 250);
  acq::GeometryTimeline kept(replay), live;
  feed(kept);
  feed(live);
  EXPECT_EQ(kept.dropped_samples(), 0u);
  EXPECT_EQ(kept.restarts(), 0u);
  const auto newest = kept.at(Clock::time_point(100s) + std::chrono::milliseconds(375 * 9));
  ASSERT_TRUE(newest);
  EXPECT_DOUBLE_EQ(newest->state.primary_deg, 90.0);
  EXPECT_GT(live.dropped_samples() + live.restarts(), 3u);  // what the live default makes of it
}
