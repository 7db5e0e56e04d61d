// The state lines drawn on every frame.
#include <gtest/gtest.h>

#include <chrono>

#include "status_lines.hpp"

namespace {

using namespace evar;
using Clock = std::chrono::steady_clock;

acquisition::FrameGeometry geometry_at(double primary, double secondary) {
  acquisition::FrameGeometry g;
  g.state.primary_deg = primary;
  g.state.secondary_deg = secondary;
  g.state.sid_mm = 1195.6;
  g.state.fluoro_on = true;
  return g;
}

TEST(StatusLines, SayTheViewTheModelAndTheRoadmapAndWhatHoldsTheRoadmapBack) {
  const auto now = Clock::now();
  node::PublishedModel preoperative;
  auto lines = node::status_lines(geometry_at(35, -15), preoperative, false, "", overlay::RoadmapMode::Both, 12.4, now);
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0], "LAO 35  CAU 15  SID 1196 mm");
  EXPECT_EQ(lines[1], "model: preoperative (undeformed), waiting for two views of the device");
  EXPECT_EQ(lines[2].substr(0, 9), "roadmap: ");
  EXPECT_NE(lines[2].find("latency 12 ms"), std::string::npos) << lines[2];

  auto g = geometry_at(-20, 10);
  g.state.fluoro_on = false;
  g.moving = true;
  g.stale = true;
  g.age_ns = 2'340'000'000;
  lines = node::status_lines(g, preoperative, false, "", overlay::RoadmapMode::Both, 0.0, now);
  EXPECT_EQ(lines[0], "RAO 20  CRA 10  SID 1196 mm  beam off  C-arm moving: roadmap hidden  geometry 2.3 s old");
  // A C-arm with zoom modes: the mode the frame was taken in.
  lines = node::status_lines(geometry_at(35, -15), preoperative, false, "", overlay::RoadmapMode::Both, 0.0, now, "zoom 20 cm");
  EXPECT_EQ(lines[0], "LAO 35  CAU 15  SID 1196 mm  zoom 20 cm");

  // No geometry: no state line.
  EXPECT_EQ(node::status_lines(std::nullopt, preoperative, false, "", overlay::RoadmapMode::Both, 0.0, now).size(), 2u);
}

TEST(StatusLines, AnAdaptedModelSaysItsFramesAndAgeAndThatItIsStaleAfterAFailure) {
  const auto now = Clock::now();
  node::PublishedModel m;
  auto adapted = std::make_shared<node::AdaptedModel>();
  adapted->frame_earlier = 12;
  adapted->frame_later = 40;
  m.adapted = adapted;
  m.ready = now - std::chrono::seconds(7);
  auto lines = node::status_lines(std::nullopt, m, false, "", overlay::RoadmapMode::Both, 0.0, now);
  EXPECT_EQ(lines[0], "model: adapted from frames 12+40, 7 s ago");
  lines = node::status_lines(std::nullopt, m, true, "", overlay::RoadmapMode::Both, 0.0, now);
  EXPECT_EQ(lines[0], "model: STALE (last adaptation failed), adapted from frames 12+40, 7 s ago");
}

// Where the node looks for the pelvis, its line comes between the model's and the roadmap's.
TEST(StatusLines, ThePelvisLineSaysWhereThePelvisWasFound) {
  const node::PublishedModel preoperative;
  const auto lines = node::status_lines(std::nullopt, preoperative, false, "12.3 mm, 4.1° from the registration; models moved with it",
                                        overlay::RoadmapMode::Both, 0.0, Clock::now());
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[1], "pelvis: 12.3 mm, 4.1° from the registration; models moved with it");
  EXPECT_EQ(lines[2].rfind("roadmap:", 0), 0u) << lines[2];
}

TEST(StatusLines, AHeldFrameSaysWhyAndForHowManyWholeSeconds) {
  EXPECT_EQ(node::held_frame_line(false, 3.9), "LAST IMAGE HELD: no video for 3 s");
  EXPECT_EQ(node::held_frame_line(true, 12.0), "LAST IMAGE HELD: no frame shown for 12 s");
}

}  // namespace
