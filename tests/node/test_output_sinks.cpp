// The snapshot sink's before/after pictures of each new model: "after" is the first frame
// drawn with the new model, not one where the compositor still showed the previous one
// while it drew the new roadmap in the background. Snapshots and video stay within their
// disk budgets.
#include <gtest/gtest.h>

#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "evar/node/output_sinks.hpp"

namespace fs = std::filesystem;
using namespace evar;

namespace {

node::ComposedFrame frame(std::uint8_t grey, std::uint64_t version, bool drawn) {
  node::ComposedFrame f;
  f.image = std::make_shared<const overlay::Image>(overlay::Image::filled(8, 6, {grey, grey, grey}));
  auto m = std::make_shared<node::PublishedModel>();
  m->version = version;
  f.model = m;
  f.P_ct = geometry::ProjectionMatrix::Identity();
  f.roadmap = drawn ? overlay::RoadmapShown::Current : overlay::RoadmapShown::Previous;
  return f;
}

int grey_of(const fs::path& png) { return cv::imread(png.string(), cv::IMREAD_GRAYSCALE).at<std::uint8_t>(0, 0); }

// A 256 x 256 frame of noise (Motion-JPEG compresses it little: tens of kB).
node::ComposedFrame noise_frame(cv::RNG& rng) {
  cv::Mat noise(256, 256, CV_8UC3);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  overlay::Image image = overlay::Image::filled(256, 256, {0, 0, 0});
  std::memcpy(image.bgr.data(), noise.data, image.bgr.size());
  node::ComposedFrame f;
  f.image = std::make_shared<const overlay::Image>(std::move(image));
  return f;
}

// The bytes of one picture (all of frame()'s are the same size), taken in `probe`.
std::uintmax_t one_picture_bytes(const fs::path& probe) {
  node::SnapshotSink sink(probe);
  sink.request();
  sink.write(frame(1, 0, true));
  return sink.bytes();
}

}  // namespace

TEST(SnapshotSink, AfterIsTheFirstFrameDrawnWithTheNewModel) {
  const fs::path dir = fs::temp_directory_path() / ("evar_snapshots_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  {
    node::SnapshotSink sink(dir);
    sink.write(frame(10, 0, true));
    sink.write(frame(20, 0, true));   // the last frame before model 1
    sink.write(frame(30, 1, false));  // model 1 published, its roadmap still being drawn
    sink.write(frame(40, 1, true));   // the first frame drawn with it
    sink.write(frame(50, 1, true));
    sink.write(frame(60, 2, false));  // model 2, superseded before it was ever drawn
    sink.write(frame(70, 3, true));
    ASSERT_EQ(sink.kept().size(), 5u);
    EXPECT_EQ(sink.deleted(), 0u);
  }
  EXPECT_EQ(grey_of(dir / "model-1-before.png"), 20);
  EXPECT_EQ(grey_of(dir / "model-1-after.png"), 40);
  EXPECT_EQ(grey_of(dir / "model-2-before.png"), 50);
  EXPECT_FALSE(fs::exists(dir / "model-2-after.png"));
  EXPECT_EQ(grey_of(dir / "model-3-before.png"), 60);
  EXPECT_EQ(grey_of(dir / "model-3-after.png"), 70);
  fs::remove_all(dir);
}

// The oldest picture cannot be deleted (a folder now stands in its place): said once by
// name, and the budget goes on with the other pictures instead of stopping at it.
TEST(SnapshotSink, APictureTheDiskRefusesToDeleteIsSaidOnceAndTheBudgetGoesOn) {
  const fs::path dir = fs::temp_directory_path() / ("evar_snapshot_refused_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::uintmax_t one = one_picture_bytes(dir / "probe");
  ASSERT_GT(one, 0u);
  node::SnapshotSink sink(dir / "run", 4 * one + one / 2);
  sink.write(frame(20, 0, true));
  sink.write(frame(21, 1, true));  // model 1: before and after
  ASSERT_TRUE(fs::is_regular_file(dir / "run" / "model-1-before.png"));
  fs::remove(dir / "run" / "model-1-before.png");
  fs::create_directories(dir / "run" / "model-1-before.png" / "in-the-way");
  std::vector<std::string> said;
  for (std::uint8_t v = 2; v <= 10; ++v) {
    try {
      sink.write(frame(static_cast<std::uint8_t>(20 + v), v, true));
    } catch (const std::runtime_error& e) {
      said.push_back(e.what());
    }
  }
  ASSERT_EQ(said.size(), 1u);
  EXPECT_NE(said[0].find("snapshots: cannot delete " + (dir / "run" / "model-1-before.png").string()), std::string::npos)
      << said[0];
  // The others were deleted as the budget asked: what is counted fits, and the files beside
  // the folder are exactly the pictures kept.
  EXPECT_LE(sink.bytes(), 4 * one + one / 2);
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir / "run")) files += e.is_regular_file() ? 1 : 0;
  EXPECT_EQ(files, sink.kept().size());
  EXPECT_EQ(grey_of(dir / "run" / "model-10-after.png"), 30);
  fs::remove_all(dir);
}

// The snapshot folder disappears (a full or unmounted disk behaves alike): each picture
// that cannot be saved is said once and given up, never tried again on every later frame
// (which cost a whole frame period each on the output thread), and pictures come back
// with the folder.
TEST(SnapshotSink, APictureThatCannotBeSavedIsSaidOnceAndNotTriedAgainOnEveryFrame) {
  const fs::path dir = fs::temp_directory_path() / ("evar_snapshot_gone_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  node::SnapshotSink sink(dir);
  sink.write(frame(10, 0, true));
  fs::remove_all(dir);
  std::vector<std::string> said;
  const auto write = [&](std::uint8_t grey, std::uint64_t version) {
    try {
      sink.write(frame(grey, version, true));
    } catch (const std::runtime_error& e) {
      said.push_back(e.what());
    }
  };
  write(11, 1);  // model 1: its "before" and "after" pictures cannot be saved
  for (std::uint8_t g = 12; g < 40; ++g) write(g, 1);
  ASSERT_EQ(said.size(), 1u) << "said again on later frames";
  EXPECT_NE(said[0].find((dir / "model-1-before.png").string()), std::string::npos) << said[0];
  EXPECT_TRUE(sink.kept().empty());
  fs::create_directories(dir);
  write(40, 2);  // model 2: the folder is back
  EXPECT_EQ(said.size(), 1u);
  EXPECT_EQ(grey_of(dir / "model-2-before.png"), 39);
  EXPECT_EQ(grey_of(dir / "model-2-after.png"), 40);
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file() ? 1 : 0;
  EXPECT_EQ(files, 2u) << "nothing of model 1 left behind";
  fs::remove_all(dir);
}

TEST(SnapshotSink, KeepsModelPicturesWithinItsBudgetAndNeverDeletesARequestedSnapshot) {
  const fs::path dir = fs::temp_directory_path() / ("evar_snapshot_budget_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::uintmax_t one = one_picture_bytes(dir / "probe");
  ASSERT_GT(one, 0u);
  {
    node::SnapshotSink sink(dir / "run", 5 * one + one / 2);
    sink.write(frame(10, 0, true));
    sink.request();
    sink.write(frame(11, 0, true));  // the clinician's picture
    for (std::uint8_t v = 1; v <= 20; ++v) {
      sink.write(frame(static_cast<std::uint8_t>(20 + v), v, true));  // before and after of model v
    }
    EXPECT_LE(sink.bytes(), 5 * one + one / 2);
    EXPECT_GE(sink.kept().size(), 4u);  // pictures differ by a few bytes: 4 or 5 fit
    EXPECT_EQ(sink.deleted() + sink.kept().size(), 40u + 1u);  // every model picture, and the requested one
    std::uintmax_t on_disk = 0;
    std::size_t files = 0;
    for (const auto& e : fs::directory_iterator(dir / "run")) {
      on_disk += e.file_size();
      ++files;
    }
    EXPECT_EQ(files, sink.kept().size());
    EXPECT_EQ(on_disk, sink.bytes());
  }
  EXPECT_TRUE(fs::exists(dir / "run" / "snapshot-0.png"));  // requested: kept though the oldest
  EXPECT_FALSE(fs::exists(dir / "run" / "model-1-before.png"));
  EXPECT_FALSE(fs::exists(dir / "run" / "model-18-after.png"));
  EXPECT_EQ(grey_of(dir / "run" / "model-20-before.png"), 39);
  EXPECT_EQ(grey_of(dir / "run" / "model-20-after.png"), 40);
  fs::remove_all(dir);
}

// The disk refuses twice: the first finished segment cannot be renamed (a folder is in
// the way), then it cannot be deleted for the budget (someone put a folder in its place).
// Each refusal is said once, naming the file; no frame is lost to it; the video goes on in
// numbered segments and the budget holds for the rest.
TEST(VideoSink, ARenameOrDeleteTheDiskRefusesIsSaidByNameAndNoFrameIsLost) {
  const fs::path dir = fs::temp_directory_path() / ("evar_video_refused_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::uintmax_t budget = 4u << 20;  // segments of 1 MiB
  std::vector<std::string> said;
  std::size_t written = 0;
  node::VideoSink sink(dir / "overlay.avi", 30.0, budget);
  fs::create_directories(dir / "overlay-0001.avi" / "in-the-way");  // the first segment's new name
  cv::RNG rng(11);
  for (int i = 0; i < 900; ++i) {
    try {
      sink.write(noise_frame(rng));
    } catch (const std::runtime_error& e) {
      said.push_back(e.what());
      if (said.size() == 1) {
        // The segment kept under its own name is replaced by a folder the sink cannot delete.
        ASSERT_TRUE(fs::is_regular_file(dir / "overlay.avi"));
        fs::remove(dir / "overlay.avi");
        fs::create_directories(dir / "overlay.avi" / "in-the-way");
      }
    }
    ++written;
  }
  sink.finish();
  ASSERT_EQ(said.size(), 2u);
  EXPECT_NE(said[0].find("video: cannot rename " + (dir / "overlay.avi").string() + " to " +
                         (dir / "overlay-0001.avi").string()),
            std::string::npos)
      << said[0];
  EXPECT_NE(said[1].find("video: cannot delete " + (dir / "overlay.avi").string() + " to stay within 4 MiB"),
            std::string::npos)
      << said[1];
  EXPECT_EQ(sink.frames(), written) << "a frame was lost to a refusal";
  // The rest of the video is in numbered segments from 0002 on, within the budget.
  ASSERT_FALSE(sink.segments().empty());
  for (const auto& p : sink.segments()) EXPECT_GE(std::stoi(p.filename().string().substr(8, 4)), 2) << p;
  EXPECT_GT(sink.segments_deleted(), 0u);
  std::uintmax_t on_disk = 0;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file()) on_disk += e.file_size();
  EXPECT_LE(on_disk, budget + (2u << 20));
  fs::remove_all(dir);
}

// A restarted node (the bedside service after a failure) writes into the same directory:
// the segment the earlier run was writing is kept under the next number, and the earlier
// run's pictures are neither overwritten nor forgotten by the budget.
TEST(VideoSink, ARestartKeepsTheSegmentTheEarlierRunWasWriting) {
  for (const std::uintmax_t budget : {std::uintmax_t{0}, std::uintmax_t{8} << 20}) {
    const fs::path dir = fs::temp_directory_path() / ("evar_video_restart_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    std::ofstream(dir / "overlay-0002.avi") << "an earlier run's finished segment";
    std::ofstream(dir / "overlay.avi") << "the segment it was writing when it stopped";
    {
      node::VideoSink sink(dir / "overlay.avi", 30.0, budget);
      sink.write(frame(10, 0, true));
      sink.finish();
      EXPECT_EQ(sink.frames(), 1u);
    }
    std::ifstream kept(dir / "overlay-0003.avi");
    std::string text;
    std::getline(kept, text);
    EXPECT_EQ(text, "the segment it was writing when it stopped") << "budget " << budget;
    EXPECT_TRUE(fs::exists(dir / "overlay-0002.avi"));
    EXPECT_GT(fs::file_size(dir / "overlay.avi"), 1000u) << "this run's video";
    fs::remove_all(dir);
  }
}

TEST(SetAsideEarlier, AnEarlierReportIsRenamedByItsTimeNeverOverwritten) {
  const fs::path dir = fs::temp_directory_path() / ("evar_set_aside_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  EXPECT_FALSE(node::set_aside_earlier(dir / "run_report.json")) << "nothing there";
  const auto at = [&](const std::string& text) {
    std::ofstream(dir / "run_report.json") << text;
    // 2026-11-22 10:11:12 UTC, the same second for both: the second gets "-1".
    fs::last_write_time(dir / "run_report.json",
                        std::chrono::file_clock::from_sys(std::chrono::sys_days{std::chrono::year{2026} / 11 / 22} +
                                                          std::chrono::hours(10) + std::chrono::minutes(11) +
                                                          std::chrono::seconds(12)));
    return node::set_aside_earlier(dir / "run_report.json");
  };
  const auto first = at("first"), second = at("second");
  ASSERT_TRUE(first && second);
  EXPECT_EQ(first->filename(), "run_report-20261122-101112Z.json");
  EXPECT_EQ(second->filename(), "run_report-20261122-101112Z-1.json");
  EXPECT_FALSE(fs::exists(dir / "run_report.json"));
  std::string text;
  std::ifstream(*first) >> text;
  EXPECT_EQ(text, "first");
  fs::remove_all(dir);
}

TEST(SnapshotSink, ARestartNeitherOverwritesNorForgetsTheEarlierRunsPictures) {
  const fs::path dir = fs::temp_directory_path() / ("evar_snapshot_restart_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  {
    node::SnapshotSink first(dir);
    first.write(frame(10, 0, true));
    first.write(frame(20, 1, true));  // model 1: before (10) and after (20)
  }
  node::SnapshotSink second(dir);
  EXPECT_EQ(second.kept().size(), 2u) << "the earlier run's pictures count";
  second.write(frame(30, 0, true));
  second.write(frame(40, 1, true));  // this run's model 1
  EXPECT_EQ(grey_of(dir / "model-1-before.png"), 10);
  EXPECT_EQ(grey_of(dir / "model-1-after.png"), 20);
  EXPECT_EQ(grey_of(dir / "model-1-before-1.png"), 30);
  EXPECT_EQ(grey_of(dir / "model-1-after-1.png"), 40);
  EXPECT_EQ(second.kept().size(), 4u);
  fs::remove_all(dir);
}

TEST(VideoSink, KeepsTheVideoWithinItsBudgetInSegmentsTheNewestKept) {
  // 256 x 256 frames of noise (Motion-JPEG compresses them little: tens of kB each), a
  // budget of 8 MiB: segments of 1 MiB are finished, numbered and the oldest deleted.
  const fs::path dir = fs::temp_directory_path() / ("evar_video_budget_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::uintmax_t budget = 8u << 20;
  // An earlier run's segments in the same directory: counted, deleted first, never overwritten.
  for (const char* old : {"overlay-0003.avi", "overlay-0007.avi"}) {
    std::ofstream(dir / old) << "an earlier run";
  }
  std::size_t written = 0;
  {
    node::VideoSink sink(dir / "overlay.avi", 30.0, budget);
    cv::RNG rng(7);
    for (int i = 0; i < 900; ++i) {
      sink.write(noise_frame(rng));
      ++written;
    }
    sink.finish();
    EXPECT_EQ(sink.frames(), written);
    ASSERT_GT(sink.segments_deleted(), 2u);  // the run needs more than the budget
    const auto kept = sink.segments();
    ASSERT_FALSE(kept.empty());
    // This run's segments are numbered on from the earlier run's (from 0008), in order, and the
    // oldest went first: what is kept is the newest run of consecutive numbers, ending with the
    // segment before the current file.
    std::vector<int> numbers;
    for (const auto& p : kept) numbers.push_back(std::stoi(p.filename().string().substr(8, 4)));
    for (std::size_t i = 1; i < numbers.size(); ++i) EXPECT_EQ(numbers[i], numbers[i - 1] + 1);
    EXPECT_EQ(numbers.front(), 8 + static_cast<int>(sink.segments_deleted()) - 2);
  }
  std::uintmax_t on_disk = 0;
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    on_disk += e.file_size();
    ++files;
  }
  EXPECT_LE(on_disk, budget + (2u << 20));  // the finished segments within budget, the current one beside them
  EXPECT_GE(files, 2u);
  EXPECT_TRUE(fs::exists(dir / "overlay.avi"));  // the newest frames, under the name asked for
  EXPECT_FALSE(fs::exists(dir / "overlay-0003.avi"));
  EXPECT_FALSE(fs::exists(dir / "overlay-0007.avi"));
  EXPECT_FALSE(fs::exists(dir / "overlay-0008.avi"));
  fs::remove_all(dir);
}
