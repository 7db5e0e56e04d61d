#include <gtest/gtest.h>
#include <unistd.h>

#include <string>

#include <chrono>
#include <filesystem>
#include <limits>
#include <mutex>
#include <thread>

#include "evar/session/session_replay.hpp"

namespace evar::session {
namespace {

namespace fs = std::filesystem;

// A clock that never waits: it jumps to every requested time and records it.
class FakeClock final : public ReplayClock {
 public:
  time_point now() override { return now_; }
  void sleep_until(time_point t, const std::atomic<bool>&) override {
    std::lock_guard lock(mutex_);
    requested.push_back(t);
    now_ = std::max(now_, t);
  }
  std::mutex mutex_;
  std::vector<time_point> requested;
  time_point now_{};
};

class Replay : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(testing::TempDir()) / ("evar_replay_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
                                          std::to_string(::getpid()));
    fs::remove_all(dir_);
    Session s;
    s.scene = "scene.json";
    s.detector = {8, 6, 0.3, 0.3};
    for (int k = 0; k < 5; ++k) {
      s.frames.push_back({10 + k, 2'000'000'000LL + k * 100'000'000LL, "fluoro", "f" + std::to_string(k) + ".png"});
      images_.push_back(cv::Mat(6, 8, CV_16UC1, cv::Scalar(1000 + 300 * k)));
      images_.back().at<std::uint16_t>(0, 0) = static_cast<std::uint16_t>(0x1234 + k);
    }
    for (int k = 0; k < 3; ++k) {
      CArmSample c;
      c.timestamp_ns = 1'950'000'000LL + k * 200'000'000LL;
      c.primary_deg = 10.0 * k;
      c.sid_mm = 1200;
      c.sod_mm = 800;
      c.fluoro_on = true;
      s.carm.push_back(c);
    }
    write_session(dir_, s, images_);
    session_ = read_session(dir_);
  }
  fs::path dir_;
  std::vector<cv::Mat> images_;
  Session session_;
};

struct Received {
  std::mutex m;
  std::vector<acquisition::Frame> frames;
  std::vector<acquisition::CArmState> carm;
  std::vector<double> primary_in_force;  // the C-arm angle last received when each frame came
  std::vector<acquisition::StreamState> states;
};

// Whether `done()` came true within 20 s: a replay that stalls fails the test instead of
// hanging it.
template <class Done>
bool eventually(Done done) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::yield();
  }
  return true;
}

void attach(SessionReplay& replay, Received& r) {
  replay.carm().start(
      [&](const acquisition::CArmState& s) {
        std::lock_guard lock(r.m);
        r.carm.push_back(s);
      },
      nullptr, nullptr);
  replay.frames().start(
      [&](const acquisition::Frame& f) {
        std::lock_guard lock(r.m);
        r.frames.push_back(f);
        r.primary_in_force.push_back(r.carm.empty() ? -1.0 : r.carm.back().primary_deg);
      },
      [&](acquisition::StreamState s, const std::string&) {
        std::lock_guard lock(r.m);
        r.states.push_back(s);
      });
}

TEST_F(Replay, DeliversEveryFrameInOrderWithItsGeometryAndLoopsWithRisingClocks) {
  SessionReplay replay(session_, {0.0, 2}, std::make_shared<FakeClock>());
  Received r;
  attach(replay, r);
  ASSERT_TRUE(replay.wait(std::chrono::seconds(20)));
  ASSERT_EQ(r.frames.size(), 10u);
  ASSERT_EQ(r.carm.size(), 6u);
  for (std::size_t i = 0; i < r.frames.size(); ++i) {
    const auto& f = r.frames[i];
    EXPECT_EQ(f.sequence, i + 1);
    EXPECT_EQ(f.format, acquisition::PixelFormat::Mono16);
    EXPECT_EQ(f.width, 8);
    // Little-endian words: the marker pixel of frame i % 5.
    EXPECT_EQ(f.pixels[0] | (f.pixels[1] << 8), 0x1234 + static_cast<int>(i % 5));
    if (i > 0) {
      EXPECT_GT(f.device_time_ns, r.frames[i - 1].device_time_ns);
    }
    // The geometry in force is the one the session says.
    EXPECT_EQ(r.primary_in_force[i], carm_at(session_, session_.frames[i % 5].timestamp_ns)->primary_deg);
  }
  EXPECT_EQ(r.frames[0].device_time_ns, session_.frames[0].timestamp_ns);
  EXPECT_EQ(replay.frames().statistics().received, 10u);
  EXPECT_EQ(replay.frames().statistics().dropped, 0u);
  EXPECT_EQ(r.states.back(), acquisition::StreamState::Stopped);
  EXPECT_TRUE(replay.progress().finished);
  EXPECT_EQ(replay.error(), "");
}

TEST_F(Replay, RealTimePacingFollowsTheRecordedTimestampsScaledBySpeed) {
  auto clock = std::make_shared<FakeClock>();
  SessionReplay replay(session_, {2.0, 1}, clock);
  Received r;
  attach(replay, r);
  ASSERT_TRUE(replay.wait(std::chrono::seconds(20)));
  // Events: C-arm at 1.95, 2.15, 2.35 s; frames at 2.0 … 2.4 s; replayed from 1.95 s at 2x.
  std::vector<std::int64_t> times;
  for (const auto& c : session_.carm) times.push_back(c.timestamp_ns);
  for (const auto& f : session_.frames) times.push_back(f.timestamp_ns);
  std::sort(times.begin(), times.end());
  ASSERT_EQ(clock->requested.size(), times.size());
  for (std::size_t i = 0; i < times.size(); ++i) {
    const double requested_ns = std::chrono::duration<double, std::nano>(clock->requested[i].time_since_epoch()).count();
    EXPECT_NEAR(requested_ns, static_cast<double>(times[i] - times[0]) / 2.0, 1.0) << i;
  }
}

TEST_F(Replay, AnUnreadableFrameEndsTheReplayWithTheFileNamed) {
  fs::remove(dir_ / "frames" / "f3.png");
  SessionReplay replay(session_, {0.0, 1}, std::make_shared<FakeClock>());
  Received r;
  attach(replay, r);
  ASSERT_TRUE(replay.wait(std::chrono::seconds(20)));
  EXPECT_EQ(r.frames.size(), 3u);  // the frames before it arrived
  EXPECT_NE(replay.error().find("f3.png"), std::string::npos) << replay.error();
  EXPECT_EQ(replay.frames().state(), acquisition::StreamState::Disconnected);
}

// Preloaded, the replay delivers the same frames, times and sequence numbers; a frame that
// cannot be decoded is found before anything is played.
TEST_F(Replay, PreloadedFramesAreTheSameAndAnUnreadableOneStopsItBeforeTheFirstFrame) {
  Received plain, preloaded;
  {
    SessionReplay replay(session_, {0.0, 2}, std::make_shared<FakeClock>());
    attach(replay, plain);
    ASSERT_TRUE(replay.wait(std::chrono::seconds(20)));
  }
  {
    SessionReplay replay(session_, {0.0, 2, true}, std::make_shared<FakeClock>());
    attach(replay, preloaded);
    ASSERT_TRUE(replay.wait(std::chrono::seconds(20)));
    EXPECT_EQ(replay.error(), "");
  }
  ASSERT_EQ(preloaded.frames.size(), plain.frames.size());
  for (std::size_t i = 0; i < plain.frames.size(); ++i) {
    EXPECT_EQ(preloaded.frames[i].pixels, plain.frames[i].pixels) << i;
    EXPECT_EQ(preloaded.frames[i].sequence, plain.frames[i].sequence) << i;
    EXPECT_EQ(preloaded.frames[i].device_time_ns, plain.frames[i].device_time_ns) << i;
  }
  EXPECT_EQ(preloaded.primary_in_force, plain.primary_in_force);

  fs::remove(dir_ / "frames" / "f3.png");
  SessionReplay replay(session_, {0.0, 1, true}, std::make_shared<FakeClock>());
  Received r;
  attach(replay, r);
  ASSERT_TRUE(replay.wait(std::chrono::seconds(20)));
  EXPECT_TRUE(r.frames.empty());
  EXPECT_NE(replay.error().find("f3.png"), std::string::npos) << replay.error();
}

TEST_F(Replay, NoCallbackAfterStopReturns) {
  Received r;  // outlives the replay, whose thread calls into it
  SessionReplay replay(session_, {0.0, 0}, std::make_shared<FakeClock>());  // forever
  attach(replay, r);
  ASSERT_TRUE(eventually([&] { return replay.progress().frames >= 20; })) << replay.progress().frames << " frames";
  replay.frames().stop();
  replay.carm().stop();
  std::size_t n;
  {
    std::lock_guard lock(r.m);
    n = r.frames.size();
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  std::lock_guard lock(r.m);
  EXPECT_EQ(r.frames.size(), n);
  EXPECT_GE(n, 20u);
  EXPECT_EQ(replay.frames().state(), acquisition::StreamState::Stopped);
}

TEST_F(Replay, StartingAgainRestartsTheReplayAndIsLiveAgain) {
  Received r, again;  // outlive the replay, whose thread calls into them
  SessionReplay replay(session_, {0.0, 0}, std::make_shared<FakeClock>());  // forever
  attach(replay, r);
  ASSERT_TRUE(eventually([&] { return replay.progress().frames >= 12; })) << replay.progress().frames << " frames";
  attach(replay, again);  // stops the running replay first
  ASSERT_TRUE(eventually([&] { return replay.progress().frames >= 3; })) << replay.progress().frames << " frames";
  EXPECT_EQ(replay.frames().state(), acquisition::StreamState::Streaming);
  EXPECT_EQ(replay.carm().state(), acquisition::StreamState::Streaming);
  replay.frames().stop();
  std::lock_guard lock(again.m);
  ASSERT_GE(again.frames.size(), 3u);
  EXPECT_EQ(again.frames[0].sequence, 1u);  // a new replay, from the start
  EXPECT_EQ(replay.frames().statistics().out_of_order, 0u);
}

TEST_F(Replay, ACallbackThatStopsItsSourceEndsTheReplayWithAnError) {
  SessionReplay replay(session_, {0.0, 1}, std::make_shared<FakeClock>());
  replay.carm().start(nullptr, nullptr, nullptr);
  replay.frames().start([&](const acquisition::Frame&) { replay.frames().stop(); }, nullptr);
  ASSERT_TRUE(replay.wait(std::chrono::seconds(20)));
  EXPECT_NE(replay.error().find("called from a replay callback"), std::string::npos) << replay.error();
  EXPECT_EQ(replay.frames().state(), acquisition::StreamState::Disconnected);
}

TEST(ReplayOptions, NegativeSpeedOrLoopsAreRefused) {
  EXPECT_THROW(SessionReplay(Session{}, {-1.0, 1}), std::invalid_argument);
  EXPECT_THROW(SessionReplay(Session{}, {1.0, -1}), std::invalid_argument);
}

// At 1e-12 the wait for a frame 1 s in (1e21 ns) overflowed the clock's 64-bit duration
// (undefined behaviour); speeds are held to what `replay --speed` takes.
TEST(ReplayOptions, SpeedsOutsideTheReplayRangeAreRefused) {
  for (const double speed : {1e-12, 0.009, 1000.5, std::numeric_limits<double>::infinity(),
                             std::numeric_limits<double>::quiet_NaN()})
    EXPECT_THROW(SessionReplay(Session{}, {speed, 1}), std::invalid_argument) << speed;
  EXPECT_NO_THROW(SessionReplay(Session{}, {kMinReplaySpeed, 1}));
  EXPECT_NO_THROW(SessionReplay(Session{}, {kMaxReplaySpeed, 1}));
  EXPECT_NO_THROW(SessionReplay(Session{}, {0.0, 1}));
}

TEST_F(Replay, ASessionWithTimestampsOutsideTheFormatsRangeIsRefused) {
  Session s = session_;
  s.frames[4].timestamp_ns = kMaxTimestampNs;
  EXPECT_THROW(SessionReplay(s, {0.0, 1}), std::invalid_argument);
  s = session_;
  s.carm[0].timestamp_ns = -1;
  EXPECT_THROW(SessionReplay(s, {0.0, 1}), std::invalid_argument);
}

// Looping forever adds a loop's length to every device time each time round. With
// timestamps at the ends of the format's range, the second loop would pass 2^63 ns (signed
// overflow, undefined; in practice device times wrapped negative and the replay went on):
// it ends with an error instead, after the frames whose times fit.
TEST_F(Replay, LoopingForeverEndsBeforeDeviceTimesOverflow) {
  Session s = session_;
  s.frames.resize(2);
  s.frames[0].timestamp_ns = 0;
  s.frames[1].timestamp_ns = kMaxTimestampNs - 1;
  s.carm.clear();
  Received r;
  SessionReplay replay(s, {0.0, 0}, std::make_shared<FakeClock>());  // forever, as fast as it goes
  attach(replay, r);
  ASSERT_TRUE(replay.wait(std::chrono::seconds(20))) << "still looping after " << replay.progress().frames << " frames";
  EXPECT_NE(replay.error().find("device time would pass 2^63 ns after 1 loops"), std::string::npos) << replay.error();
  std::lock_guard lock(r.m);
  ASSERT_EQ(r.frames.size(), 2u);
  EXPECT_EQ(r.frames[1].device_time_ns, kMaxTimestampNs - 1);
  EXPECT_EQ(replay.frames().state(), acquisition::StreamState::Disconnected);
}

}  // namespace
}  // namespace evar::session
