#include "status_lines.hpp"

#include <spdlog/fmt/fmt.h>

#include <cmath>

#include "evar/node/frame_view.hpp"

namespace evar::node {

std::vector<std::string> status_lines(const std::optional<acquisition::FrameGeometry>& g, const PublishedModel& model,
                                      bool last_adaptation_failed, const std::string& pelvis, overlay::RoadmapMode mode,
                                      double latency_ms, std::chrono::steady_clock::time_point now,
                                      const std::string& zoom) {
  std::vector<std::string> lines;
  if (g) {
    std::string state = fmt::format("{}  SID {:.0f} mm", angulation_text(g->state.primary_deg, g->state.secondary_deg),
                                    g->state.sid_mm);
    if (!zoom.empty()) state += "  " + zoom;
    if (!g->state.fluoro_on) state += "  beam off";
    if (g->moving) state += "  C-arm moving: roadmap hidden";
    if (g->stale) state += fmt::format("  geometry {:.1f} s old", static_cast<double>(g->age_ns) * 1e-9);
    lines.push_back(std::move(state));
  }
  if (!model.adapted) {
    lines.push_back("model: preoperative (undeformed), waiting for two views of the device");
  } else {
    lines.push_back(fmt::format("model: {} from frames {}+{}, {:.0f} s ago",
                                last_adaptation_failed ? "STALE (last adaptation failed), adapted" : "adapted",
                                model.adapted->frame_earlier, model.adapted->frame_later,
                                std::chrono::duration<double>(now - model.ready).count()));
  }
  if (!pelvis.empty()) lines.push_back("pelvis: " + pelvis);
  lines.push_back(fmt::format("roadmap: {}   latency {:.0f} ms", overlay::to_string(mode), latency_ms));
  return lines;
}

std::string held_frame_line(bool showing_fails, double held_s) {
  return fmt::format("LAST IMAGE HELD: {} for {:.0f} s", showing_fails ? "no frame shown" : "no video", std::floor(held_s));
}

}  // namespace evar::node
