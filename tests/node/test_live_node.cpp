// The live node end to end on a replayed simulated session: a failed reconstruction, a
// silent C-arm link and a stalled video are reported while the video goes on (the adapted
// overlay and its error against the truth: tests/app/test_live_node_evaluation.cpp).
#include <gtest/gtest.h>

#include <spdlog/sinks/ostream_sink.h>

#include <algorithm>
#include <filesystem>
#include <sstream>
#include <thread>

#include "evar/node/live_node.hpp"
#include "evar/node/logging.hpp"
#include "evar/node/output_sinks.hpp"
#include "evar/session/session_replay.hpp"
#include "evar/sim/session_generator.hpp"
#include "support/live_node_replay.hpp"

namespace {

using namespace evar;
namespace fs = std::filesystem;
using test::LiveNodeReplay;

TEST_F(LiveNodeReplay, AFailedReconstructionIsReportedAndTheVideoGoesOn) {
  node::NodeOptions o = options();
  o.backpressure = true;
  o.adaptation.max_mean_residual_px = 1e-9;  // every reconstruction is refused
  node::LiveNode node(*scene_, o, {});
  ASSERT_TRUE(replay_through(node));
  const node::NodeStatistics s = node.statistics();
  EXPECT_EQ(s.frames_composited, session().frames.size());
  EXPECT_GE(s.adaptation_failures, 1u);
  EXPECT_EQ(s.adaptations, 0u);
  EXPECT_NE(s.last_failure.find("refused"), std::string::npos) << s.last_failure;
  EXPECT_EQ(s.last_failure.rfind("frames ", 0), 0u) << "the failed pair is named: " << s.last_failure;
  EXPECT_EQ(node.model()->version, 0u);  // the preoperative model stays
}

// What each composed frame said on screen, in order.
class StatusRecorder final : public node::OutputSink {
 public:
  struct Shown {
    std::uint64_t version = 0;
    bool adapted = false;
    bool held = false;
    std::uint64_t sequence = 0;
    overlay::StatusBlock status;
  };
  std::string name() const override { return "status recorder"; }
  void write(const node::ComposedFrame& f) override {
    frames.push_back({f.model ? f.model->version : 0, f.model && f.model->adapted, f.held, f.sequence, f.status});
  }
  std::vector<Shown> frames;  // read after the node stopped
};

bool any_contains(const std::vector<std::string>& lines, const std::string& text) {
  return std::any_of(lines.begin(), lines.end(), [&](const std::string& l) { return l.find(text) != std::string::npos; });
}

std::size_t count_of(const std::string& log, const std::string& text) {
  std::size_t n = 0;
  for (std::size_t at = log.find(text); at != std::string::npos; at = log.find(text, at + 1)) ++n;
  return n;
}

TEST_F(LiveNodeReplay, AfterALaterAdaptationFailsTheLastGoodModelStaysOnScreenAndBothScreenAndLogSaySo) {
  // The session as recorded until the C-arm leaves the second view; from then on the link
  // reports the table 300 mm off (a wrong table reading, an unannounced table move), so
  // the next pair's two views disagree and no device can come of them. A pause before the
  // third view leaves the first pair time to be adapted, however slow the build.
  session::Session faulty = session();
  const auto view_of = [&](std::int64_t t) {
    const session::CArmSample* c = session::carm_at(faulty, t);
    return std::make_pair(std::lround(c->primary_deg), std::lround(c->secondary_deg));
  };
  std::vector<std::pair<long, long>> views;
  std::int64_t last_of_second_view = 0;
  for (const auto& f : faulty.frames) {
    const auto v = view_of(f.timestamp_ns);
    if (views.empty() || views.back() != v) views.push_back(v);
    if (views.size() == 2) last_of_second_view = f.timestamp_ns;
  }
  ASSERT_GE(views.size(), 3u) << "the session has fewer than three views";
  constexpr std::int64_t kPauseNs = 40'000'000'000;
  for (auto& c : faulty.carm)
    if (c.timestamp_ns > last_of_second_view) {
      c.timestamp_ns += kPauseNs;
      c.table_mm[0] += 300.0;
    }
  std::uint64_t first_faulty_frame = 0;
  for (auto& f : faulty.frames)
    if (f.timestamp_ns > last_of_second_view) {
      if (!first_faulty_frame) first_faulty_frame = static_cast<std::uint64_t>(f.frame);
      f.timestamp_ns += kPauseNs;
    }

  std::ostringstream log;
  auto log_sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(log);
  node::log().sinks().push_back(log_sink);
  node::NodeOptions o = options();
  o.backpressure = true;
  o.timeline.stale_after = std::chrono::milliseconds(60'000);  // the link reports changes only
  auto recorder = std::make_unique<StatusRecorder>();
  StatusRecorder* shown = recorder.get();
  std::vector<std::unique_ptr<node::OutputSink>> sinks;
  sinks.push_back(std::move(recorder));
  node::LiveNode node(*scene_, o, std::move(sinks));
  session::SessionReplay replay(faulty, {8.0, 1});
  node.start(replay.frames(), replay.carm());
  ASSERT_TRUE(replay.wait(std::chrono::seconds(120)));
  node.stop();
  node::log().sinks().pop_back();

  const node::NodeStatistics s = node.statistics();
  ASSERT_GE(s.adaptations, 1u) << s.last_failure;
  ASSERT_GE(s.adaptation_failures, 1u);
  const auto model = node.model();
  ASSERT_TRUE(model->adapted);
  EXPECT_LT(model->adapted->frame_later, first_faulty_frame) << "a model came of the disagreeing views";
  EXPECT_EQ(model->version, s.adaptations);

  // On screen: from the first frame that says so, every frame keeps showing the adapted
  // model, marks it stale and names the failure.
  std::size_t from = shown->frames.size();
  for (std::size_t i = 0; i < shown->frames.size() && from == shown->frames.size(); ++i)
    if (any_contains(shown->frames[i].status.alerts, "last good model kept")) from = i;
  ASSERT_LT(from, shown->frames.size()) << "no frame said the adaptation failed";
  for (std::size_t i = from; i < shown->frames.size(); ++i) {
    const auto& f = shown->frames[i];
    ASSERT_TRUE(f.adapted) << "frame " << i;
    EXPECT_EQ(f.version, model->version) << "frame " << i;
    EXPECT_TRUE(any_contains(f.status.lines, "STALE (last adaptation failed)")) << "frame " << i;
  }
  // In the log: each model once, and the failure as a warning that names what was kept.
  const std::string text = log.str();
  EXPECT_EQ(count_of(text, "adapted model from frames"), s.adaptations) << text;
  EXPECT_GE(count_of(text, "[warning] frames "), 1u) << text;
  EXPECT_GE(count_of(text, "; last good model kept"), 1u) << text;
}

// A C-arm link that sends one state and falls silent.
class SilentCArm final : public acquisition::CArmGeometrySource {
 public:
  explicit SilentCArm(acquisition::CArmState first) : first_(first) {}
  void start(StateCallback on_state, StreamCallback, NoticeCallback) override {
    first_.host_arrival = std::chrono::steady_clock::now();
    on_state(first_);
  }
  void stop() override {}
  acquisition::StreamState state() const override { return acquisition::StreamState::Streaming; }
  std::string description() const override { return "a C-arm that falls silent"; }

 private:
  acquisition::CArmState first_;
};

// The sink that records what a node shows.
std::vector<std::unique_ptr<node::OutputSink>> recording(StatusRecorder*& shown) {
  auto recorder = std::make_unique<StatusRecorder>();
  shown = recorder.get();
  std::vector<std::unique_ptr<node::OutputSink>> sinks;
  sinks.push_back(std::move(recorder));
  return sinks;
}

// A frame source whose frames `from` to `to` (sequence numbers) cannot be read: their
// rows are said to be one byte long (a grabber whose layout broke).
// How a frame is spoiled: a stride shorter than a row, or a buffer missing its last rows
// (read as declared, it would run past its end).
enum class Spoil { Stride, Truncated };

class SpoiledFrames final : public acquisition::FrameSource {
 public:
  SpoiledFrames(acquisition::FrameSource& inner, std::uint64_t from, std::uint64_t to, Spoil how)
      : inner_(inner), from_(from), to_(to), how_(how) {}
  void start(FrameCallback on_frame, StateCallback on_state) override {
    inner_.start(
        [this, on_frame](const acquisition::Frame& f) {
          if (f.sequence < from_ || f.sequence >= to_) return on_frame(f);
          acquisition::Frame spoiled = f;
          if (how_ == Spoil::Stride) spoiled.stride_bytes = 1;
          else spoiled.pixels.resize(spoiled.pixels.size() / 2);
          on_frame(spoiled);
        },
        std::move(on_state));
  }
  void stop() override { inner_.stop(); }
  acquisition::StreamState state() const override { return inner_.state(); }
  acquisition::SequenceStats statistics() const override { return inner_.statistics(); }
  std::string description() const override { return "frames spoiled for a while"; }

 private:
  acquisition::FrameSource& inner_;
  std::uint64_t from_, to_;
  Spoil how_;
};

// Frames keep coming but cannot be shown: the screen does not freeze on the last good
// frame as if it were live. It is held, marked so, with the reason among the alerts, and
// the live video comes back by itself with the good frames.
TEST_F(LiveNodeReplay, FramesThatCannotBeShownLeaveTheLastGoodOneHeldAndMarked) {
  for (const auto& [how, reason] : {std::pair{Spoil::Stride, "frame stride 1 bytes is shorter than a row"},
                                    std::pair{Spoil::Truncated, "frame of 512 x 512 Mono16 holds 262144 bytes, not 524288"}}) {
    SCOPED_TRACE(reason);
    StatusRecorder* shown = nullptr;
    node::LiveNode node(*scene_, stall_options(), recording(shown));
    // The session's first fluoroscopy run is frames 1-60 at 15/s; replayed at 2x, frames
    // 20-49 are a second of unreadable video within it.
    session::SessionReplay replay(session(), {2.0, 1});
    SpoiledFrames frames(replay.frames(), 20, 50, how);
    node.start(frames, replay.carm());
    ASSERT_TRUE(replay.wait(std::chrono::seconds(60)));
    node.stop();

    const auto first_held = std::find_if(shown->frames.begin(), shown->frames.end(), [](const auto& f) { return f.held; });
    ASSERT_NE(first_held, shown->frames.end()) << "no frame was held while the video could not be shown";
    ASSERT_NE(first_held, shown->frames.begin());
    const std::uint64_t last_good = std::prev(first_held)->sequence;
    EXPECT_LT(last_good, 20u);
    const auto back = std::find_if(first_held, shown->frames.end(), [](const auto& f) { return !f.held; });
    ASSERT_NE(back, shown->frames.end()) << "the live video did not come back";
    EXPECT_GE(back->sequence, 50u);
    EXPECT_LE(back->sequence, 60u) << "the live video came back only after the run";
    // 1 s without a frame shown, less the 300 ms before the stall, at one held frame per
    // 200 ms: up to 4; at least 2 leaves room for a slow sanitizer build.
    EXPECT_GE(back - first_held, 2);
    EXPECT_TRUE(any_contains(first_held->status.alerts, "no frame shown for 300 ms"));
    for (auto it = first_held; it != back; ++it) {
      EXPECT_EQ(it->sequence, last_good) << "a held frame that is not the last good one";
      ASSERT_FALSE(it->status.alerts.empty());
      EXPECT_NE(it->status.alerts.front().find("LAST IMAGE HELD: no frame shown for"), std::string::npos)
          << it->status.alerts.front();
      EXPECT_TRUE(any_contains(it->status.alerts, std::string("frame not shown: ") + reason)) << reason;
    }
    EXPECT_FALSE(any_contains(back->status.alerts, "no frame shown for")) << "the stall was not cleared";
  }
}

TEST_F(LiveNodeReplay, ASilentCArmLinkAndAStalledVideoAreReportedWhileFramesAreShown) {
  StatusRecorder* shown = nullptr;
  node::LiveNode node(*scene_, stall_options(), recording(shown));
  SilentCArm carm(session::to_carm_state(session().carm.front(), 0));
  session::SessionReplay replay(session(), {8.0, 1});
  node.start(replay.frames(), carm);
  ASSERT_TRUE(replay.wait(std::chrono::seconds(60)));
  // The replay is over: no more frames, which the node must notice.
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  node.stop();
  const node::NodeStatistics s = node.statistics();
  EXPECT_GT(s.frames_composited, session().frames.size() / 2);
  EXPECT_GT(s.stale_geometry_frames, session().frames.size() / 2);
  EXPECT_EQ(s.video_stalls, 1u);

  // While there is no video the screen is not left frozen: the last frame comes again,
  // marked held and saying so first among the alerts, until the node stops. From the stall
  // (300 ms) to the end (1500 ms) at one every 200 ms that is up to 6; at least 2 leaves
  // room for a compose thread slowed by a sanitizer build.
  ASSERT_FALSE(shown->frames.empty());
  const auto first_held = std::find_if(shown->frames.begin(), shown->frames.end(), [](const auto& f) { return f.held; });
  ASSERT_NE(first_held, shown->frames.end()) << "no frame was held";
  const std::uint64_t last_sequence = std::prev(first_held)->sequence;
  for (auto it = first_held; it != shown->frames.end(); ++it) {
    ASSERT_TRUE(it->held) << "a frame after the video stopped that is not the held one";
    EXPECT_EQ(it->sequence, last_sequence) << "held frames show the last frame that came";
    ASSERT_FALSE(it->status.alerts.empty());
    EXPECT_NE(it->status.alerts.front().find("LAST IMAGE HELD: no video for"), std::string::npos) << it->status.alerts.front();
    EXPECT_TRUE(any_contains(it->status.alerts, "no video for 300 ms"));
  }
  const auto held = static_cast<std::uint64_t>(shown->frames.end() - first_held);
  EXPECT_EQ(s.frames_held, held);
  EXPECT_GE(held, 2u);
  EXPECT_LE(held, 7u);
  // No backpressure here: the output queue may have dropped frames, never held ones
  // (nothing else is queued then).
  EXPECT_EQ(s.frames_composited + s.frames_held, shown->frames.size() + s.dropped_output);
}

// A C-arm link that streams the replay's states and, after its `at`-th state, gives one
// notice, as a link does when its line turns noisy or the C-arm sends a warning.
class NoticingCArm final : public acquisition::CArmGeometrySource {
 public:
  NoticingCArm(acquisition::CArmGeometrySource& inner, std::size_t at, std::string notice)
      : inner_(inner), at_(at), notice_(std::move(notice)) {}
  void start(StateCallback on_state, StreamCallback on_stream, NoticeCallback on_notice) override {
    inner_.start(
        [this, on_state, on_notice](const acquisition::CArmState& s) {
          on_state(s);
          if (++states_ == at_) on_notice({acquisition::LinkNotice::Kind::BadFrames, notice_});
        },
        std::move(on_stream), nullptr);
  }
  void stop() override { inner_.stop(); }
  acquisition::StreamState state() const override { return inner_.state(); }
  std::string description() const override { return "a C-arm link with news"; }

 private:
  acquisition::CArmGeometrySource& inner_;
  std::size_t at_, states_ = 0;
  std::string notice_;
};

// News from a link that streams on (bad frames between good messages, a C-arm warning) is
// shown on the live frames beside the roadmap for a while, logged once, and goes by itself;
// it is not taken for the link going down.
TEST_F(LiveNodeReplay, ANoticeFromTheCArmLinkIsShownForAWhileAndLoggedOnce) {
  const std::string notice = "C-arm link serial /dev/ttyX: 12 bad frames since the last report (13 bad frames so far)";
  std::ostringstream log;
  auto log_sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(log);
  node::log().sinks().push_back(log_sink);
  node::NodeOptions o = options();
  o.carm_notice_hold = std::chrono::milliseconds(2000);
  StatusRecorder* shown = nullptr;
  node::LiveNode node(*scene_, o, recording(shown));
  // At 4x the session's 10 states a second, the 20th comes half a second in, with some
  // 4.5 s of replay to go.
  session::SessionReplay replay(session(), {4.0, 1});
  NoticingCArm carm(replay.carm(), 20, notice);
  node.start(replay.frames(), carm);
  ASSERT_TRUE(replay.wait(std::chrono::seconds(60)));
  node.stop();
  node::log().sinks().pop_back();
  const std::string text = log.str();

  const auto saying = [&](const StatusRecorder::Shown& f) { return any_contains(f.status.alerts, notice); };
  const auto first = std::find_if(shown->frames.begin(), shown->frames.end(), saying);
  ASSERT_NE(first, shown->frames.end()) << "no frame showed the notice";
  const auto gone = std::find_if_not(first, shown->frames.end(), saying);
  ASSERT_NE(gone, shown->frames.end()) << "the notice stayed on screen to the end";
  // Two seconds at 60 frames a second: about 120; at least 2 leaves room for a slow
  // sanitizer build on a loaded machine.
  EXPECT_GE(gone - first, 2);
  for (auto it = first; it != gone; ++it) EXPECT_FALSE(it->held) << "the video went on";
  EXPECT_TRUE(std::none_of(gone, shown->frames.end(), saying)) << "the notice came back";
  EXPECT_EQ(count_of(text, notice), 1u) << text;
  EXPECT_EQ(count_of(text, "[warning] " + notice), 1u) << text;
  EXPECT_EQ(node.statistics().carm_notices, 1u);
  EXPECT_EQ(node.statistics().last_carm_notice, notice);
}

}  // namespace
