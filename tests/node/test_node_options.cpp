// The node's options, checked in one place: a setting no node could run with is refused
// before any thread starts, by its field name, with what is wrong.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>

#include "evar/node/node_options.hpp"

using evar::node::check_options;
using evar::node::NodeOptions;
using namespace std::chrono_literals;

namespace {

NodeOptions valid() {
  NodeOptions o;
  o.detector = {.cols = 640, .rows = 480, .row_spacing_mm = 0.3, .col_spacing_mm = 0.3};
  return o;
}

// The message check_options gives for `valid()` changed by `change` ("" when accepted).
std::string refusal(const std::function<void(NodeOptions&)>& change) {
  NodeOptions o = valid();
  change(o);
  try {
    check_options(o);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return {};
}

}  // namespace

TEST(NodeOptions, TheDefaultsWithADetectorAreAccepted) { EXPECT_NO_THROW(check_options(valid())); }

TEST(NodeOptions, EachSettingNoNodeCouldRunWithIsRefusedByName) {
  const struct {
    std::function<void(NodeOptions&)> change;
    const char* says;
  } cases[] = {
      {[](NodeOptions& o) { o.detector.cols = 0; }, "node options: detector: 0 x 480 pixels"},
      {[](NodeOptions& o) { o.detector.col_spacing_mm = -0.3; }, "node options: detector.col_spacing_mm:"},
      {[](NodeOptions& o) { o.registration(0, 3) = std::nan(""); }, "node options: registration: not finite"},
      {[](NodeOptions& o) { o.registration(3, 0) = 1; }, "node options: registration: the last row must be 0 0 0 1"},
      {[](NodeOptions& o) { o.registration(0, 0) = -1; }, "node options: registration: the 3 x 3 part is singular or mirrors space"},
      {[](NodeOptions& o) { o.candidate.device_diameter_mm = 0; }, "node options: candidate.device_diameter_mm:"},
      {[](NodeOptions& o) { o.candidate.min_confidence = 1.5; }, "node options: candidate.min_confidence: 1.5"},
      {[](NodeOptions& o) { o.adaptation.max_share_outside = -0.1; }, "node options: adaptation.max_share_outside:"},
      {[](NodeOptions& o) { o.adaptation.orientation_outside_mm = 2.0; },
       "node options: adaptation.orientation_outside_mm: must be finite and no less than adaptation.reading_margin_mm"},
      {[](NodeOptions& o) { o.timeline.stale_after = 0ms; }, "node options: timeline.stale_after: 0 ms"},
      {[](NodeOptions& o) { o.compositor.supersample = 0; }, "node options: compositor.supersample: 0; must be 1 to 8"},
      {[](NodeOptions& o) { o.held_frame_interval = 0ms; }, "node options: held_frame_interval: 0 ms"},
      {[](NodeOptions& o) { o.carm_notice_hold = -5ms; }, "node options: carm_notice_hold: -5 ms"},
      // A queue of 0 used to be taken as 1 without a word.
      {[](NodeOptions& o) { o.input_queue = 0; }, "node options: input_queue: 0 frames"},
      {[](NodeOptions& o) { o.output_queue = 0; }, "node options: output_queue: 0 frames"},
      // The parts with checks of their own are asked too.
      {[](NodeOptions& o) { o.frame_loss.raise_fraction = 2; }, "node options: frame loss monitor:"},
  };
  for (const auto& c : cases) {
    const std::string message = refusal(c.change);
    EXPECT_EQ(message.rfind(c.says, 0), 0u) << "expected \"" << c.says << "...\", got \"" << message << "\"";
  }
}
