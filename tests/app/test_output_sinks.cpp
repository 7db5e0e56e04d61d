// The snapshot sink's before/after pictures of each new model: "after" is the first frame
// drawn with the new model, not one where the compositor still showed the previous one
// while it drew the new roadmap in the background.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <memory>

#include <opencv2/imgcodecs.hpp>

#include "output_sinks.hpp"

namespace fs = std::filesystem;
using namespace evar;

namespace {

app::ComposedFrame frame(std::uint8_t grey, std::uint64_t version, bool drawn) {
  app::ComposedFrame f;
  f.image = std::make_shared<const overlay::Image>(overlay::Image::filled(8, 6, {grey, grey, grey}));
  auto m = std::make_shared<app::PublishedModel>();
  m->version = version;
  f.model = m;
  f.P_ct = geometry::ProjectionMatrix::Identity();
  f.roadmap = drawn ? overlay::RoadmapShown::Current : overlay::RoadmapShown::Previous;
  return f;
}

int grey_of(const fs::path& png) { return cv::imread(png.string(), cv::IMREAD_GRAYSCALE).at<std::uint8_t>(0, 0); }

}  // namespace

TEST(SnapshotSink, AfterIsTheFirstFrameDrawnWithTheNewModel) {
  const fs::path dir = fs::temp_directory_path() / ("evar_snapshots_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  {
    app::SnapshotSink sink(dir);
    sink.write(frame(10, 0, true));
    sink.write(frame(20, 0, true));   // the last frame before model 1
    sink.write(frame(30, 1, false));  // model 1 published, its roadmap still being drawn
    sink.write(frame(40, 1, true));   // the first frame drawn with it
    sink.write(frame(50, 1, true));
    sink.write(frame(60, 2, false));  // model 2, superseded before it was ever drawn
    sink.write(frame(70, 3, true));
    ASSERT_EQ(sink.written().size(), 5u);
  }
  EXPECT_EQ(grey_of(dir / "model-1-before.png"), 20);
  EXPECT_EQ(grey_of(dir / "model-1-after.png"), 40);
  EXPECT_EQ(grey_of(dir / "model-2-before.png"), 50);
  EXPECT_FALSE(fs::exists(dir / "model-2-after.png"));
  EXPECT_EQ(grey_of(dir / "model-3-before.png"), 60);
  EXPECT_EQ(grey_of(dir / "model-3-after.png"), 70);
  fs::remove_all(dir);
}
