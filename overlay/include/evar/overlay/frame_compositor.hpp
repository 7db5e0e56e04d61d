#pragma once
// The live roadmap: each grabbed frame window-levelled to 8-bit grey, then the vessel
// roadmap (translucent fill, crisp outline), the landmark rings with labels and the
// reconstructed device drawn through the frame's own projection, then a status block.
//
// The roadmap layer is rendered once per (projection, model, mode, size) and blended into
// every frame: it is drawn over black and over white, which gives per pixel and channel its
// premultiplied colour B and its transmittance K = W − B, so out = B + g·K/255 for the
// frame's grey g. Every drawing operation is a blend linear in the background, so this is
// exact up to rounding (a few grey levels). While the C-arm is still (its readings moving
// the model by under a quarter pixel) a frame costs only the look-up table and
// the blend.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/triangle_mesh.hpp"
#include "evar/overlay/mesh_preview.hpp"

namespace evar::overlay {

/// A view of the caller's grey pixels (not copied).
struct GreyFrame {
  int width = 0, height = 0;
  int stride_bytes = 0;                ///< bytes per row
  int bits = 8;                        ///< 8, or 16 (also 12-bit data in 16-bit little-endian words)
  const std::uint8_t* data = nullptr;
};

/// Display window in the frame's units: grey = 255 · (value − (level − window/2)) / window.
struct WindowLevel {
  double window = 0.0;  ///< 0 = automatic: the frame's 1st to 99th percentile
  double level = 0.0;
};

enum class RoadmapMode { Undeformed, Adapted, Both };
const char* to_string(RoadmapMode mode);
/// "undeformed", "adapted" or "both"; nullopt otherwise.
std::optional<RoadmapMode> parse_roadmap_mode(std::string_view text);

/// What the roadmap shows (CT LPS mm; the projection maps CT to pixels).
struct RoadmapModel {
  std::vector<geometry::TriangleMesh> initial;        ///< the preoperative vessels
  std::vector<geometry::ControlPoint> initial_landmarks;
  std::vector<geometry::TriangleMesh> adapted;        ///< empty until a model is adapted
  std::vector<geometry::ControlPoint> adapted_landmarks;
  geometry::Polyline device;                          ///< the reconstructed device (may be empty)
};

struct StatusBlock {
  std::vector<std::string> lines;   ///< white
  std::vector<std::string> alerts;  ///< amber, under the lines
};

struct CompositorOptions {
  int supersample = 2;        ///< roadmap antialiasing (DrawOptions::supersample)
  WindowLevel window_level;
  /// Draw the roadmap layer on a worker thread, so no frame waits for it: until the layer
  /// for a new view is ready the frame shows no roadmap, and until the layer for a new model
  /// is ready it shows the previous model's (drawn for this very view); the status block
  /// says so. Off: compose() draws the layer itself before returning (stills, tests).
  bool layer_in_background = false;
};

/// What compose() drew in its last frame.
enum class RoadmapShown {
  None,      ///< no roadmap (no projection or model, or its layer is still being drawn)
  Current,   ///< the model asked for
  Previous,  ///< the previous model, at this view, while the asked one is drawn
};

namespace detail {
struct RoadmapLayer;
class LayerWorker;
}  // namespace detail

class FrameCompositor {
 public:
  /// std::invalid_argument for a supersample outside 1..8 or a negative window.
  explicit FrameCompositor(CompositorOptions options = {});
  ~FrameCompositor();
  FrameCompositor(const FrameCompositor&) = delete;
  FrameCompositor& operator=(const FrameCompositor&) = delete;

  /// The composited frame. `P_ct` null draws no roadmap (no usable geometry); `model` null
  /// likewise. Mode Adapted or Both with a model that has no adapted meshes draws the
  /// initial vessels as in Undeformed. Throws std::invalid_argument for a frame whose size,
  /// stride, depth or data pointer is wrong (nothing about its pixel values).
  Image compose(const GreyFrame& frame, const geometry::ProjectionMatrix* P_ct,
                const std::shared_ptr<const RoadmapModel>& model, RoadmapMode mode, const StatusBlock& status);

  /// How often the roadmap layer was rendered (a cache miss: another model, mode or size,
  /// or a projection that moves the model by a quarter pixel or more), for tests and reports.
  std::size_t layer_renders() const;
  /// What the last composed frame showed of the roadmap.
  RoadmapShown last_roadmap() const { return last_shown_; }
  /// Why the last composed frame has no roadmap although one was asked for, when its layer
  /// could not be drawn (in the background: an out-of-memory or a model the drawing
  /// refuses; the frame says so too); empty otherwise. Drawing is retried after a second.
  const std::string& last_layer_error() const { return last_layer_error_; }
  /// The display window of the last frame (after automatic choice).
  WindowLevel last_window() const { return last_window_; }

 private:
  void update_lut(const GreyFrame& frame);

  CompositorOptions options_;
  std::shared_ptr<const detail::RoadmapLayer> layer_, spare_;  // the layer in use, and the other one kept
  std::unique_ptr<detail::LayerWorker> worker_;        // with layer_in_background
  std::size_t own_renders_ = 0;
  RoadmapShown last_shown_ = RoadmapShown::None;
  std::string last_layer_error_;
  std::vector<std::uint8_t> lut_;
  int lut_bits_ = 0;
  WindowLevel lut_window_{-1.0, 0.0};
  WindowLevel last_window_;
  std::vector<std::uint16_t> samples_;
};

/// The Overlay a mode draws (colours as in compose), for stills and other sinks.
Overlay roadmap_overlay(const RoadmapModel& model, RoadmapMode mode);

}  // namespace evar::overlay
