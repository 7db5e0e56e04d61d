// Recording what sources deliver as a session: a session replayed in real time through the
// acquisition interfaces and recorded again must come back with every frame's pixels, every
// C-arm state, and the same geometry in force at every frame.
#include <gtest/gtest.h>
#include <unistd.h>

#include <string>

#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <nlohmann/json.hpp>

#include "evar/base/input_error.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/session/session_recorder.hpp"
#include "evar/session/session_replay.hpp"
#include "evar/sim/example_scene.hpp"
#include "support/error_message.hpp"
#include "support/killed_recording.hpp"
#include "support/ramp_frames.hpp"

namespace evar::session {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

class Recording : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::path(testing::TempDir()) /
            ("evar_record_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
             std::to_string(::getpid()));
    fs::remove_all(root_);
    sim::ExampleSceneParams p;
    p.aorta_vertices = 800;
    p.iliac_vertices = 400;
    sim::write_example_scene(sim::make_example_scene(p), root_ / "plan");
    Session s;
    s.scene = "scene.json";
    s.detector = {40, 30, 0.3, 0.3};
    images_ = evar::test::add_ramp_frames(s, 12, 60'000'000LL, {5000, 97, 13, 0});
    // The C-arm changes between frames (never within 15 ms of one), so the state in force
    // at each frame is unambiguous.
    for (int k = 0; k < 5; ++k) {
      CArmSample c;
      c.timestamp_ns = 970'000'000LL + k * 150'000'000LL;
      c.primary_deg = -20.0 + 7.5 * k;
      c.secondary_deg = 3.0 * k;
      c.sid_mm = 1180 + k;
      c.sod_mm = 790;
      c.table_mm = {1.0 * k, -2.0, 0.5};
      c.fluoro_on = true;
      c.moving = k == 2;
      s.carm.push_back(c);
    }
    write_session(root_ / "original", s, images_);
    original_ = read_session(root_ / "original");
  }
  void TearDown() override { fs::remove_all(root_); }

  RecorderOptions options() const {
    RecorderOptions o;
    o.out = root_ / "recorded";
    o.scene = root_ / "plan" / "scene.json";
    o.ct_to_carm(0, 3) = 12.5;
    o.pixel_spacing_mm = 0.154;
    return o;
  }

  fs::path root_;
  std::vector<cv::Mat> images_;
  Session original_;
};

TEST_F(Recording, AReplayedSessionRecordsBackFrameForFrameWithItsGeometry) {
  SessionReplay replay(original_, {1.0, 1});
  SessionRecorder recorder(options(), replay.frames(), replay.carm());
  recorder.start();
  ASSERT_TRUE(replay.wait(20s));
  const Session out = recorder.finish();

  const Session back = read_session(root_ / "recorded");
  ASSERT_EQ(back.frames.size(), 12u);
  ASSERT_EQ(back.carm.size(), 5u);
  EXPECT_EQ(back.detector.cols, 40);
  EXPECT_DOUBLE_EQ(back.detector.row_spacing_mm, 0.154);
  EXPECT_DOUBLE_EQ(back.ct_to_carm(0, 3), 12.5);
  for (std::size_t k = 0; k < 12; ++k) {
    const cv::Mat img = read_session_frame(back, k);
    EXPECT_EQ(cv::norm(img, images_[k], cv::NORM_INF), 0.0) << "frame " << k;
    // The same C-arm state is in force at the frame as in the original.
    const CArmSample* was = carm_at(original_, original_.frames[k].timestamp_ns);
    const CArmSample* now = carm_at(back, back.frames[k].timestamp_ns);
    ASSERT_TRUE(was && now);
    EXPECT_DOUBLE_EQ(now->primary_deg, was->primary_deg) << "frame " << k;
    EXPECT_EQ(now->moving, was->moving) << "frame " << k;
  }
  for (std::size_t k = 0; k < 5; ++k) {
    EXPECT_NEAR(back.carm[k].secondary_deg, original_.carm[k].secondary_deg, 1e-9);
    EXPECT_NEAR(back.carm[k].table_mm[0], original_.carm[k].table_mm[0], 1e-9);
  }
  // Intervals survive (real-time replay; a loaded 2-core machine may delay a frame's
  // delivery by some tens of ms).
  const double span_ms = 1e-6 * static_cast<double>(back.frames.back().timestamp_ns - back.frames.front().timestamp_ns);
  EXPECT_NEAR(span_ms, 660.0, 60.0);

  // The patient travels with the session.
  const auto scene = geometry::load_scene(root_ / "recorded" / back.scene);
  EXPECT_EQ(scene.vessels.size(), geometry::load_scene(root_ / "plan" / "scene.json").vessels.size());

  const auto report = nlohmann::json::parse(std::ifstream(root_ / "recorded" / "record_report.json"));
  EXPECT_EQ(report["frames"]["written"], 12);
  EXPECT_EQ(report["carm"]["samples"], 5);
  EXPECT_EQ(report["session_written"], true);
  EXPECT_EQ(out.frames.size(), 12u);
}

// Sources the test drives by hand, on its own thread: what each delivers and when it
// "arrived" are the test's to choose.
class ScriptedFrames final : public acquisition::FrameSource {
 public:
  void start(FrameCallback on_frame, StateCallback) override { on_frame_ = std::move(on_frame); }
  void stop() override { on_frame_ = nullptr; }
  acquisition::StreamState state() const override { return acquisition::StreamState::Streaming; }
  acquisition::SequenceStats statistics() const override { return {}; }
  std::string description() const override { return "scripted frames"; }
  void deliver(const acquisition::Frame& f) const { on_frame_(f); }

 private:
  FrameCallback on_frame_;
};

class ScriptedCArm final : public acquisition::CArmGeometrySource {
 public:
  void start(StateCallback on_state, StreamCallback, NoticeCallback on_notice) override {
    on_state_ = std::move(on_state);
    on_notice_ = std::move(on_notice);
  }
  void stop() override { on_state_ = nullptr; }
  acquisition::StreamState state() const override { return acquisition::StreamState::Streaming; }
  std::string description() const override { return "scripted C-arm"; }
  void deliver(const acquisition::CArmState& s) const { on_state_(s); }
  void notice(const std::string& n) const { on_notice_({acquisition::LinkNotice::Kind::BadFrames, n}); }

 private:
  StateCallback on_state_;
  NoticeCallback on_notice_;
};

TEST_F(Recording, FramesAtTheStartOfAStreamAreTimedAsExactlyAsTheRest) {
  // A camera's first frames often reach the host late (the stream thread is still being
  // scheduled, buffers queue); an estimate that sees only earlier frames stamps them late
  // by as much, and the geometry in force at them comes out wrong. The recording is timed
  // from all its frames, later ones too.
  ScriptedFrames frames;
  ScriptedCArm carm;
  RecorderOptions o = options();
  o.max_queued_frames = 100;  // delivered at once, faster than the disk takes them
  SessionRecorder recorder(o, frames, carm);
  recorder.start();
  const std::int64_t host0 = 9'000'000'000'000, device0 = 123'000'000'000;  // the camera's own epoch
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> jitter_us(300, 3000);
  std::vector<std::int64_t> truth;
  for (int k = 0; k < 80; ++k) {
    acquisition::Frame f;
    f.format = acquisition::PixelFormat::Mono8;
    f.width = f.height = f.stride_bytes = 4;
    f.pixels.assign(16, static_cast<std::uint8_t>(k));
    f.sequence = static_cast<std::uint64_t>(k);
    const std::int64_t captured = host0 + k * 25'000'000LL;  // 40 fps
    f.device_time_ns = device0 + (captured - host0);
    const std::int64_t late_ns = k < 12 ? 150'000'000 : 0;  // the first 12 frames queue up
    f.host_arrival = std::chrono::steady_clock::time_point(std::chrono::nanoseconds(captured + late_ns + jitter_us(rng) * 1000LL));
    f.device_time_on_host = f.host_arrival;  // what a live estimate with no better sample gives
    f.device_clock = true;
    frames.deliver(f);
    truth.push_back(captured);
    if (k % 10 == 0) {
      acquisition::CArmState c;
      c.device_time_ns = 5'000'000'000 + (captured - host0);
      c.host_arrival = std::chrono::steady_clock::time_point(std::chrono::nanoseconds(captured));
      c.primary_deg = k;
      c.sid_mm = 1200;
      c.sod_mm = 800;
      carm.deliver(c);
    }
  }
  const Session s = recorder.finish();
  ASSERT_EQ(s.frames.size(), truth.size());
  for (std::size_t k = 0; k < truth.size(); ++k) {
    // Off by no more than the smallest delivery delay around the frame (0.3 to 3 ms).
    const double off_ms = 1e-6 * static_cast<double>(s.frames[k].timestamp_ns - truth[k]);
    EXPECT_GE(off_ms, 0.0) << "frame " << k;
    EXPECT_LT(off_ms, 3.0) << "frame " << k;
  }
  // What was written is what finish() returned, and reads back.
  const Session back = read_session(root_ / "recorded");
  ASSERT_EQ(back.frames.size(), truth.size());
  for (std::size_t k = 0; k < truth.size(); ++k) EXPECT_EQ(back.frames[k].timestamp_ns, s.frames[k].timestamp_ns) << k;
  ASSERT_EQ(back.carm.size(), 8u);
  for (std::size_t k = 0; k < back.carm.size(); ++k) {
    EXPECT_EQ(back.carm[k].primary_deg, 10.0 * static_cast<double>(k));
    EXPECT_EQ(back.carm[k].timestamp_ns, s.carm[k].timestamp_ns);
  }
}

acquisition::Frame grey_frame(std::uint64_t k) {
  acquisition::Frame f;
  f.format = acquisition::PixelFormat::Mono8;
  f.width = f.height = f.stride_bytes = 4;
  f.pixels.assign(16, static_cast<std::uint8_t>(k));
  f.sequence = k;
  f.host_arrival = std::chrono::steady_clock::now();
  f.device_time_on_host = f.host_arrival;
  return f;
}

acquisition::CArmState carm_state(double primary_deg, double sid_mm, double sod_mm) {
  acquisition::CArmState c;
  c.host_arrival = std::chrono::steady_clock::now();
  c.device_time_ns = c.host_arrival.time_since_epoch().count();
  c.primary_deg = primary_deg;
  c.sid_mm = sid_mm;
  c.sod_mm = sod_mm;
  return c;
}

// A C-arm sending a state the format refuses (SID beyond 5000 mm, an angle out of range or
// not a number, SOD beyond SID) once cost the whole recording: the session was written and
// then refused by every reader. Such states are counted and left out.
TEST_F(Recording, CArmStatesTheFormatRefusesAreLeftOutAndCounted) {
  ScriptedFrames frames;
  ScriptedCArm carm;
  SessionRecorder recorder(options(), frames, carm);
  recorder.start();
  carm.deliver(carm_state(10, 1200, 800));
  carm.deliver(carm_state(10, 6000, 800));
  carm.deliver(carm_state(200, 1200, 800));
  carm.deliver(carm_state(std::numeric_limits<double>::quiet_NaN(), 1200, 800));
  carm.deliver(carm_state(12, 700, 800));
  carm.deliver(carm_state(14, 1200, 800));
  carm.notice("C-arm link serial /dev/ttyX: 1 bad frames so far");  // kept in the report
  carm.notice("C-arm warning: tube temperature high");
  for (std::uint64_t k = 0; k < 3; ++k) frames.deliver(grey_frame(k));
  const Session s = recorder.finish();
  EXPECT_EQ(s.carm.size(), 2u);
  EXPECT_EQ(recorder.statistics().carm_samples, 2u);
  EXPECT_EQ(recorder.statistics().carm_refused, 4u);
  const Session back = read_session(root_ / "recorded");
  ASSERT_EQ(back.carm.size(), 2u);
  EXPECT_EQ(back.carm[1].primary_deg, 14.0);
  const auto report = nlohmann::json::parse(std::ifstream(root_ / "recorded" / "record_report.json"));
  EXPECT_EQ(report["carm"]["refused_invalid"], 4);
  EXPECT_EQ(report["carm"]["samples"], 2);
  EXPECT_EQ(report["carm"]["notices"], 2);
  EXPECT_EQ(report["carm"]["recent_notices"],
            nlohmann::json::array({"C-arm link serial /dev/ttyX: 1 bad frames so far", "C-arm warning: tube temperature high"}));
}

// A frame the disk refused was only the last error: received, written, not recorded and
// refused did not add up. And when the session files could not be written, no report was.
TEST_F(Recording, FramesTheDiskRefusesAreCountedAndTheReportIsWrittenWhenTheSessionIsNot) {
  ScriptedFrames frames;
  ScriptedCArm carm;
  SessionRecorder recorder(options(), frames, carm);
  recorder.start();
  const fs::path out = root_ / "recorded";
  fs::create_directories(out / "frames" / "f0000002.png");  // the second frame's PNG cannot be written
  carm.deliver(carm_state(10, 1200, 800));
  for (std::uint64_t k = 0; k < 4; ++k) frames.deliver(grey_frame(k));
  fs::create_directories(out / "carm.csv");  // nor can the C-arm stream
  try {
    recorder.finish();
    ADD_FAILURE() << "finish() wrote a session over a directory where carm.csv goes";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("record --recover"), std::string::npos) << e.what();
  }
  const RecorderStatistics st = recorder.statistics();
  EXPECT_EQ(st.frames_write_failed, 1u);
  EXPECT_EQ(st.frames_written, 3u);
  EXPECT_EQ(st.frames_received, st.frames_written + st.frames_not_recorded + st.frames_refused + st.frames_write_failed);
  ASSERT_TRUE(fs::exists(out / "record_report.json"));
  const auto report = nlohmann::json::parse(std::ifstream(out / "record_report.json"));
  EXPECT_EQ(report["frames"]["write_failed"], 1);
  EXPECT_EQ(report["session_written"], false);
  EXPECT_NE(report["last_error"].get<std::string>().find("carm.csv"), std::string::npos) << report.dump(2);

  // The journal stayed: with room for carm.csv, the recording is recovered in full.
  fs::remove(out / "carm.csv");
  const RecoveredRecording r = recover_recording(out);
  EXPECT_EQ(r.frames_journaled, 3u);
  EXPECT_EQ(r.frames_lost, 0u);
  const Session back = read_session(out);
  EXPECT_EQ(back.frames.size(), 3u);
  EXPECT_EQ(back.carm.size(), 1u);
}

// The whole recording lived in memory until finish(): a recorder killed by SIGKILL (the OOM
// killer, a crash) left PNGs and nothing a reader could take. Its journal now becomes a
// session with every frame whose PNG is whole and every C-arm state, timed as finish() would.
TEST_F(Recording, ARecordingKilledMidwayIsRecoveredFromItsJournal) {
  const fs::path out = root_ / "recorded";
  const int status = evar::test::record_then_kill(options(), original_);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "child status " << status;
  EXPECT_THROW(read_session(out), base::InputError);  // no session.json: nothing a reader takes
  if (fs::exists(out / "record_report.json")) {  // the periodic report, if one was written before the kill
    EXPECT_EQ(nlohmann::json::parse(std::ifstream(out / "record_report.json"))["in_progress"], true);
  }

  // The kill may also cut the PNG being written and the journal row after it.
  const fs::path last_png = out / "frames" / "f0000012.png";
  fs::resize_file(last_png, fs::file_size(last_png) - 5);
  std::ofstream(out / "journal" / "frames.csv", std::ios::app) << "13,2000000000,fluoro,f00000";
  // And a frame killed before its rename leaves its partial file.
  std::ofstream(out / "frames" / "f0000013.png.partial-4242-0-1f") << "half a PNG";

  const RecoveredRecording r = recover_recording(out);
  EXPECT_EQ(r.partial_files_removed, 1u);
  EXPECT_FALSE(fs::exists(out / "frames" / "f0000013.png.partial-4242-0-1f"));
  EXPECT_EQ(r.frames_journaled, 12u);
  EXPECT_EQ(r.frames_lost, 1u);
  EXPECT_TRUE(r.cut_row_skipped);
  EXPECT_EQ(r.carm_samples, 5u);
  EXPECT_FALSE(fs::exists(out / "journal"));

  const Session back = read_session(out);
  ASSERT_EQ(back.frames.size(), 11u);
  ASSERT_EQ(back.carm.size(), 5u);
  EXPECT_DOUBLE_EQ(back.detector.col_spacing_mm, 0.154);
  EXPECT_DOUBLE_EQ(back.ct_to_carm(0, 3), 12.5);
  for (std::size_t k = 0; k < back.frames.size(); ++k) {
    EXPECT_EQ(cv::norm(read_session_frame(back, k), images_[k], cv::NORM_INF), 0.0) << "frame " << k;
    const CArmSample* was = carm_at(original_, original_.frames[k].timestamp_ns);
    const CArmSample* now = carm_at(back, back.frames[k].timestamp_ns);
    ASSERT_TRUE(was && now);
    EXPECT_DOUBLE_EQ(now->primary_deg, was->primary_deg) << "frame " << k;
  }
  const auto recovered = nlohmann::json::parse(std::ifstream(out / "record_report.json"));
  EXPECT_EQ(recovered["session_written"], true);
  EXPECT_EQ(recovered["recovered"]["frames"], 11);
  EXPECT_EQ(recovered["recovered"]["frames_lost"], 1);

  // A finished session, or a directory that never held a recording, has nothing to recover.
  EXPECT_NE(evar::test::error_message([&] { recover_recording(out); }).find("a finished session"), std::string::npos);
  EXPECT_NE(evar::test::error_message([&] { recover_recording(root_ / "plan"); }).find("no recording journal"),
            std::string::npos);
}

TEST_F(Recording, GreyLevelsOfEightAndTwelveBitFramesKeepTheirMeaning) {
  acquisition::Frame f;
  f.format = acquisition::PixelFormat::Mono8;
  f.width = 2;
  f.height = 1;
  f.stride_bytes = 4;  // padded rows are read by stride
  f.pixels = {0, 255, 9, 9};
  cv::Mat m = to_session_image(f);
  EXPECT_EQ(m.at<std::uint16_t>(0, 0), 0);
  EXPECT_EQ(m.at<std::uint16_t>(0, 1), 65535);
  f.format = acquisition::PixelFormat::Mono12;
  f.pixels = {0xFF, 0x0F, 0x00, 0x08};  // 4095, 2048
  m = to_session_image(f);
  EXPECT_EQ(m.at<std::uint16_t>(0, 0), 65520);
  EXPECT_EQ(m.at<std::uint16_t>(0, 1), 32768);
  f.pixels.resize(2);
  EXPECT_THROW(to_session_image(f), std::invalid_argument);
}

TEST_F(Recording, RefusesAnOutputThatHoldsSomethingAndReportsAnEmptyRecording) {
  fs::create_directories(root_ / "recorded");
  std::ofstream(root_ / "recorded" / "keep.txt") << "precious";
  SessionReplay replay(original_, {0.0, 1});
  EXPECT_THROW(SessionRecorder(options(), replay.frames(), replay.carm()), std::invalid_argument);
  fs::remove_all(root_ / "recorded");

  // Sources that deliver nothing: finish() says so and leaves the report.
  Session empty = original_;
  empty.frames.clear();
  SessionReplay nothing(empty, {0.0, 1});
  SessionRecorder recorder(options(), nothing.frames(), nothing.carm());
  recorder.start();
  nothing.wait(5s);
  try {
    recorder.finish();
    ADD_FAILURE() << "an empty recording was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no frame"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::exists(root_ / "recorded" / "record_report.json"));
}

// A box on a C-arm's video output records the monitor's picture: the session carries the
// video mapping and the detector behind it, whether it is finished or recovered from the
// journal of a killed recorder; a mapping that does not fit the detector is refused first.
TEST_F(Recording, AVideoOutputIsRecordedWithItsMappingAndRecoveredWithIt) {
  RecorderOptions o = options();
  geometry::VideoMapping m;  // the 40 x 30 frames show a 64 x 64 detector in [5, 0, 30, 30]
  m.video_cols = 40;
  m.video_rows = 30;
  m.image_rect = {5, 0, 30, 30};
  m.mirror = true;
  o.video_mapping = m;
  o.detector_px = {64, 48};
  {
    SessionReplay unused(original_, {0.0, 1});
    try {
      SessionRecorder refused(o, unused.frames(), unused.carm());
      ADD_FAILURE() << "a mapping that does not fit the detector was taken";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("record: video mapping: image_rect_px [5, 0, 30, 30]"), std::string::npos)
          << e.what();
    }
  }
  o.detector_px = {64, 64};
  {
    SessionReplay replay(original_, {0.0, 1});
    SessionRecorder recorder(o, replay.frames(), replay.carm());
    recorder.start();
    ASSERT_TRUE(replay.wait(20s));
    recorder.finish();
  }
  const Session back = read_session(o.out);
  ASSERT_TRUE(back.video_mapping);
  EXPECT_EQ(geometry::video_mapping_json(*back.video_mapping), geometry::video_mapping_json(m));
  EXPECT_EQ(back.detector.cols, 64);
  EXPECT_EQ(back.detector.rows, 64);
  EXPECT_DOUBLE_EQ(back.detector.col_spacing_mm, 0.154);
  ASSERT_EQ(back.frames.size(), 12u);
  EXPECT_EQ(read_session_frame(back, 3).size(), cv::Size(40, 30));
  EXPECT_EQ(read_detector_frame(back, 3).size(), cv::Size(64, 64));

  fs::remove_all(o.out);
  const int status = evar::test::record_then_kill(o, original_);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "child status " << status;
  recover_recording(o.out);
  const Session recovered = read_session(o.out);
  ASSERT_TRUE(recovered.video_mapping);
  EXPECT_EQ(geometry::video_mapping_json(*recovered.video_mapping), geometry::video_mapping_json(m));
  EXPECT_EQ(recovered.detector.cols, 64);
}

// A C-arm with zoom modes (issue 31): the recording lists them and keeps each state's mode,
// also through a kill and its recovery; a recording that lists none keeps the states, says
// how many named a mode, and its session takes their frames as the detector's.
TEST_F(Recording, EachCArmStatesZoomModeIsRecordedWithTheModesAndRecovered) {
  const auto mode = [](int number, const std::string& name, double spacing_mm) {
    return geometry::centred_zoom_mode(number, name, 40, 30, spacing_mm);
  };
  Session zoomed = original_;
  zoomed.zoom_modes = {mode(1, "12 cm", 0.3), mode(2, "8 cm", 0.2)};
  // The last state in a mode the list lacks (3).
  for (std::size_t k = 0; k < zoomed.carm.size(); ++k) zoomed.carm[k].zoom_mode = k < 2 ? 1 : k < 4 ? 2 : 3;
  write_session(root_ / "zoomed", zoomed, images_);
  zoomed = read_session(root_ / "zoomed");
  const auto modes_of = [](const Session& s) {
    std::vector<int> m;
    for (const auto& c : s.carm) m.push_back(c.zoom_mode);
    return m;
  };

  // Records `zoomed` afresh; what the recorder counted.
  const auto record = [&](const RecorderOptions& with) {
    fs::remove_all(with.out);
    SessionReplay replay(zoomed, {0.0, 1});
    SessionRecorder recorder(with, replay.frames(), replay.carm());
    recorder.start();
    EXPECT_TRUE(replay.wait(20s));
    recorder.finish();
    return recorder.statistics();
  };
  RecorderOptions o = options();
  o.pixel_spacing_mm = 0.3;
  o.detector_px = {40, 30};
  o.zoom_modes = zoomed.zoom_modes;
  EXPECT_EQ(record(o).carm_zoom_unlisted, 1u);
  const Session back = read_session(o.out);
  EXPECT_EQ(geometry::zoom_modes_json(back.zoom_modes), geometry::zoom_modes_json(zoomed.zoom_modes));
  EXPECT_EQ(modes_of(back), modes_of(zoomed)) << "the unlisted mode is kept as said, not dropped";
  EXPECT_FALSE(zoom_known(back, back.carm.back()));
  EXPECT_EQ(back.frames.size(), 12u);

  // node.json's fixed mode wins over what the link says.
  RecorderOptions fixed = o;
  fixed.zoom_mode = 2;
  EXPECT_EQ(record(fixed).carm_zoom_unlisted, 0u);
  EXPECT_EQ(modes_of(read_session(o.out)), std::vector<int>(zoomed.carm.size(), 2));

  // Killed midway: the journal keeps the modes.
  fs::remove_all(o.out);
  const int status = evar::test::record_then_kill(o, zoomed);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "child status " << status;
  recover_recording(o.out);
  const Session recovered = read_session(o.out);
  EXPECT_EQ(geometry::zoom_modes_json(recovered.zoom_modes), geometry::zoom_modes_json(zoomed.zoom_modes));
  EXPECT_EQ(modes_of(recovered), modes_of(zoomed));

  // Without the modes: every state kept as the detector's, and counted.
  fs::remove_all(o.out);
  RecorderOptions plain = options();
  EXPECT_EQ(record(plain).carm_zoom_unlisted, zoomed.carm.size());
  const Session without = read_session(plain.out);
  EXPECT_EQ(without.carm.size(), zoomed.carm.size());
  EXPECT_TRUE(without.zoom_modes.empty());
  EXPECT_EQ(modes_of(without), std::vector<int>(zoomed.carm.size(), 0));
  const auto report = nlohmann::json::parse(std::ifstream(plain.out / "record_report.json"));
  EXPECT_EQ(report["carm"]["zoom_unlisted"], zoomed.carm.size()) << report.dump(2);

  // The journal of a recorder from before the zoom mode's column is still recovered (mode 0).
  fs::remove_all(plain.out);
  {
    const int status = evar::test::record_then_kill(plain, original_);
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "child status " << status;
    const fs::path journal = plain.out / "journal" / "carm.csv";
    std::ifstream in(journal);
    std::string old_form, row;
    while (std::getline(in, row)) old_form += row.substr(0, row.rfind(',')) + "\n";  // the last column off
    in.close();
    ASSERT_EQ(old_form.substr(0, old_form.find('\n')),
              "device_time_ns,host_arrival_ns,primary_deg,secondary_deg,sid_mm,sod_mm,table_x_mm,table_y_mm,table_z_mm,"
              "fluoro_on,moving");
    std::ofstream(journal, std::ios::trunc) << old_form;
  }
  recover_recording(plain.out);
  const Session old_journal = read_session(plain.out);
  EXPECT_EQ(old_journal.carm.size(), original_.carm.size());
  EXPECT_EQ(modes_of(old_journal), std::vector<int>(original_.carm.size(), 0));

  // Modes whose frames could not share a session are refused before anything is recorded.
  fs::remove_all(o.out);
  o.zoom_modes[1].cols = 20;
  o.zoom_modes[1].width_mm = 20 * 0.2;
  SessionReplay unused(zoomed, {0.0, 1});
  try {
    SessionRecorder refused(o, unused.frames(), unused.carm());
    ADD_FAILURE() << "modes of two frame sizes were taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("record: zoom_modes: zoom mode 2's frames are 20 x 30"), std::string::npos) << e.what();
  }
}

TEST(CArmOnHostClock, FollowsADriftingCArmClockThroughJumpsAndRestarts) {
  // Ten minutes at 10 Hz from a C-arm whose crystal runs 100 ppm fast (60 ms over the run,
  // what one offset for the whole recording would get wrong), arriving 1 to 25 ms late; the
  // C-arm clock jumps 10 s ahead at 4 min and restarts from zero at 7 min.
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> delay_ms(1, 25);
  std::vector<acquisition::CArmState> states;
  std::vector<std::int64_t> truth;  // host time at which each state was measured
  const std::int64_t host0 = 5'000'000'000'000;
  for (int i = 0; i < 6000; ++i) {
    const std::int64_t host = host0 + i * 100'000'000LL;
    const std::int64_t t = host - host0;
    std::int64_t device = 777'000'000'000 + t + t / 10'000;  // +100 ppm
    if (i >= 2400) device += 10'000'000'000;                 // jumps ahead
    if (i >= 4200) device = t - 420'000'000'000;             // restarted at zero
    acquisition::CArmState s;
    s.device_time_ns = device;
    s.host_arrival = std::chrono::steady_clock::time_point(std::chrono::nanoseconds(host + (i % 50 == 0 ? 1 : delay_ms(rng)) * 1'000'000LL));
    s.primary_deg = i * 0.01;
    states.push_back(s);
    truth.push_back(host);
  }
  const auto mapped = carm_on_host_clock(states);
  ASSERT_EQ(mapped.size(), states.size());
  double worst_ms = 0.0;
  for (std::size_t i = 0; i < mapped.size(); ++i) {
    worst_ms = std::max(worst_ms, std::abs(static_cast<double>(mapped[i].timestamp_ns - truth[i])) * 1e-6);
    if (i > 0) {
      ASSERT_GE(mapped[i].timestamp_ns, mapped[i - 1].timestamp_ns);
    }
  }
  // Within the drift over ±30 s (3 ms) plus the smallest delay (1 ms).
  EXPECT_LT(worst_ms, 4.5);
  EXPECT_DOUBLE_EQ(mapped[4321].primary_deg, states[4321].primary_deg);
}

}  // namespace
}  // namespace evar::session
