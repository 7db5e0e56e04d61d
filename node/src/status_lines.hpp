#pragma once
// The status block's state lines, as drawn on every frame: the C-arm's angulation and
// distance with what keeps the roadmap back, which model is shown and how old it is, where
// the pelvis was found, the roadmap mode and the latency; and the line that marks a held frame.
#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include "evar/acquisition/geometry_timeline.hpp"
#include "evar/node/output_sink.hpp"
#include "evar/overlay/frame_compositor.hpp"

namespace evar::node {

/// `geometry`: the frame's C-arm geometry, if any; `last_adaptation_failed`: the model shown
/// is the last good one, not the newest pair's; `pelvis`: the pelvis's line
/// (NodeStatistics::pelvis_status, none when empty); `now`: for the model's age; `zoom`: the
/// zoom mode's label on the C-arm's line ("zoom 32 cm"; none when empty).
std::vector<std::string> status_lines(const std::optional<acquisition::FrameGeometry>& geometry, const PublishedModel& model,
                                      bool last_adaptation_failed, const std::string& pelvis, overlay::RoadmapMode mode,
                                      double latency_ms, std::chrono::steady_clock::time_point now,
                                      const std::string& zoom = "");

/// "LAST IMAGE HELD: no video for 3 s" (whole seconds; `showing_fails`: frames came but
/// none could be shown).
std::string held_frame_line(bool showing_fails, double held_s);

}  // namespace evar::node
