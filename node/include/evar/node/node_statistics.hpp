#pragma once
// What the live node counts: frames in, composited, held and dropped, analyses, pairs and
// adaptations, health events, and latency percentiles.
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace evar::node {

struct Percentiles {
  double p50 = 0, p99 = 0, max = 0;
  std::size_t n = 0;
};

struct NodeStatistics {
  std::uint64_t frames_in = 0, frames_composited = 0, frames_with_roadmap = 0;
  std::uint64_t dropped_input = 0, dropped_output = 0, frames_lost_by_source = 0;
  std::uint64_t frames_wrong_size = 0;
  /// Frames taken in a zoom mode node.json does not list, or with none said among several:
  /// shown without a roadmap (issue 31).
  std::uint64_t frames_zoom_unknown = 0;
  /// Analysed frames whose image area did not show fluoroscopy (under a video mapping:
  /// geometry::not_fluoroscopy), not searched for a device.
  std::uint64_t frames_not_fluoroscopy = 0;
  /// Under a video mapping: frames checked for fitting it, those that did not fit, and what
  /// the last misfit was (NodeOptions::video_mapping_check).
  std::uint64_t video_mapping_checks = 0, video_mapping_misfits = 0;
  std::string last_video_mapping_misfit;
  /// Views (by their bones, node::check_bone_orientation) and view pairs (by their device,
  /// node::check_picture_orientation) whose picture orientation was checked, those that
  /// read right only with the picture turned or mirrored, and what the last of those said.
  std::uint64_t orientation_checks = 0, orientation_misfits = 0;
  std::string last_orientation_misfit;
  /// Checks after which the screen said the picture is turned or mirrored (two in a row
  /// agreeing), and the last thing it said.
  std::uint64_t orientation_alerts = 0;
  std::string last_orientation_alert;
  std::uint64_t frames_held = 0;     ///< the last frame shown again while there was no video (not in frames_composited)
  /// Frames and pairs handed on but never analysed or adapted: replaced by a newer one, or
  /// left when the node stopped (with readaptations below, they make the adaptations).
  std::uint64_t analysed = 0, analysis_skipped = 0, candidates = 0, pairs = 0, pairs_superseded = 0;
  /// The pair on screen adapted once more because the pelvis moved the models (no new view):
  /// pairs + readaptations = adaptations + adaptation_failures + pairs_superseded.
  std::uint64_t readaptations = 0;
  std::uint64_t analysis_waited = 0;  ///< frames whose analysis waited for an adaptation to finish
  std::uint64_t analysis_replaced = 0;  ///< of those, frames skipped for a newer one (in analysis_skipped)
  std::uint64_t adaptations = 0, adaptation_failures = 0;
  std::uint64_t video_stalls = 0, stale_geometry_frames = 0, moving_frames = 0, sink_errors = 0;
  std::uint64_t frame_loss_alerts = 0;  ///< times the source began losing frames (NodeOptions::frame_loss)
  std::uint64_t carm_notices = 0;       ///< the C-arm link's news: bad frames, the C-arm's warnings
  std::string last_carm_notice;
  Percentiles latency_ms;            ///< frame arrival → composited, over the last kLatencyWindow frames
  Percentiles adaptation_ms;         ///< second view's frame arrival → model ready, over the last kLatencyWindow adaptations
  std::string last_failure;          ///< the last adaptation failure ("" if none)
  /// Models shown with part of the device left outside their vessels past the warning
  /// threshold (deform::leaves_device_outside), and the last model's measures.
  std::uint64_t models_device_outside = 0;
  double last_device_outside_length_mm = 0.0, last_device_outside_max_depth_mm = 0.0;
  std::optional<std::int64_t> carm_clock_offset_ns;
  /// The pelvis found in the bones (NodeOptions::pelvis): views of it kept, registrations
  /// tried, found, and the times the models were moved with it; the last registration's
  /// outcome (node::describe) and, when the models were moved, the pose they were moved by.
  std::uint64_t pelvis_views = 0, pelvis_registrations = 0, pelvis_found = 0, pelvis_moves = 0;
  std::string last_pelvis;
  std::string pelvis_status;  ///< the status line's text ("" when the node does not look for the pelvis)
  std::optional<std::array<double, 3>> pelvis_shift_mm;
  double pelvis_turn_deg = 0.0;
};

/// p50/p99/max of a sample (nearest rank); zeros for none.
Percentiles percentiles(std::vector<double> values);

}  // namespace evar::node
