#pragma once
// The live node (`evarnode run`): frames and C-arm states from acquisition's interfaces
// (hardware or a replayed session) in, composited roadmap frames out to the sinks.
//
//   source thread   → input queue (4, oldest dropped) →
//   compose thread  : the frame's layout checked, geometry at the frame's time
//                     (GeometryTimeline), roadmap composited with the current model,
//                     status block; eligible frames (beam on, C-arm still, geometry fresh)
//                     offered to analysis (latest only)
//                   → output queue (8, oldest dropped) → output thread → sinks
//   analysis thread : device segmentation, candidates, view pairs → adaptation (latest only);
//                     the first frame of each view of the bones → pelvis thread
//   pelvis thread   : the pelvis registered in the bones; found elsewhere, the models are
//                     moved with it for the next adaptation (node/pelvis_tracker.hpp)
//   adaptation thread: reconstruction and deformation; the new model is published and the
//                     compositor switches to it on the next frame
//
// Nothing waits on the deformation, and no queue grows without bound: every drop is
// counted. Health (a stalled or lost source, stale geometry, a failed adaptation) goes to
// the log when it changes and onto the frames while it lasts; the last good model stays.
#include <cstddef>
#include <memory>
#include <vector>

#include "evar/acquisition/carm_geometry_source.hpp"
#include "evar/acquisition/frame_source.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/node/node_options.hpp"
#include "evar/node/node_statistics.hpp"
#include "evar/node/output_sink.hpp"
#include "evar/overlay/frame_compositor.hpp"

namespace evar::node {

class LiveNode {
 public:
  /// The scene must outlive the node. Throws base::InputError for a scene the
  /// deformation cannot use, std::invalid_argument for bad options.
  LiveNode(const geometry::Scene& scene, NodeOptions options, std::vector<std::unique_ptr<OutputSink>> sinks);
  ~LiveNode();
  LiveNode(const LiveNode&) = delete;
  LiveNode& operator=(const LiveNode&) = delete;

  /// Latency percentiles are over this many most recent frames (about 55 min at 30 fps).
  static constexpr std::size_t kLatencyWindow = 100'000;

  /// Starts the threads and the sources (C-arm first). The sources must outlive stop().
  /// Throws what the sources throw when they cannot be opened (nothing left running). A node
  /// runs once: starting it again after stop() throws std::logic_error (its queues are closed).
  void start(acquisition::FrameSource& frames, acquisition::CArmGeometrySource& carm);
  /// Stops the sources, lets the queued frames through, waits for a running adaptation,
  /// finishes the sinks, and lets go of the sources (statistics() keeps their last counts).
  /// Idempotent.
  void stop();

  void set_mode(overlay::RoadmapMode mode);
  overlay::RoadmapMode mode() const;
  NodeStatistics statistics() const;
  std::shared_ptr<const PublishedModel> model() const;

 private:
  class Impl;  // the threads, queues, alerts and counts (live_node.cpp)
  std::unique_ptr<Impl> impl_;
};

}  // namespace evar::node
