// The node's alerts: conditions stay until cleared, events clear themselves, the log hears
// of each once.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "alert_board.hpp"
#include "support/node_screen.hpp"

namespace {

using namespace evar;
using namespace std::chrono_literals;
using test::count_of;

TEST(AlertBoard, AConditionStaysUntilClearedAndTheLogHearsOfItOnceAndOfItsEnd) {
  test::LogCapture log;
  node::AlertBoard board;
  board.set("geometry", "C-arm geometry stale", std::nullopt);
  board.set("geometry", "C-arm geometry stale", std::nullopt);  // said again: not news
  board.set("video-loss", "video losing frames", std::nullopt);
  EXPECT_EQ(board.current(), (std::vector<std::string>{"C-arm geometry stale", "video losing frames"}));
  EXPECT_EQ(board.current("geometry"), (std::vector<std::string>{"video losing frames"}));
  board.clear("geometry");
  board.clear("geometry");  // nothing left to clear: no second line
  EXPECT_EQ(board.current(), (std::vector<std::string>{"video losing frames"}));
  const std::string text = log.text();
  EXPECT_EQ(count_of(text, "[warning] C-arm geometry stale"), 1u) << text;
  EXPECT_EQ(count_of(text, "resolved: C-arm geometry stale"), 1u) << text;
}

TEST(AlertBoard, AnEventClearsItselfAfterItsHoldAndIsNewsAgainWhenItComesBack) {
  test::LogCapture log;
  node::AlertBoard board;
  board.set("adaptation", "frames 3+9: too short", 300ms);
  board.set("adaptation", "frames 3+9: too short", 300ms);  // within the hold: not news
  EXPECT_EQ(board.current().size(), 1u);
  std::this_thread::sleep_for(600ms);
  EXPECT_TRUE(board.current().empty());
  board.set("adaptation", "frames 3+9: too short", 60s);  // back after expiring: news again
  board.set("adaptation", "frames 4+9: too short", 60s);  // another text: news
  EXPECT_EQ(board.current(), (std::vector<std::string>{"frames 4+9: too short"}));
  const std::string text = log.text();
  EXPECT_EQ(count_of(text, "[warning] frames 3+9: too short"), 2u) << text;
  EXPECT_EQ(count_of(text, "[warning] frames 4+9: too short"), 1u) << text;
}

}  // namespace
