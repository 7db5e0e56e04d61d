#pragma once
// The roadmap layer of the frame compositor: the roadmap drawn once over black and once
// over white for a (projection, model, mode, size), giving per pixel and channel the
// premultiplied colour B and the transmittance K = W − B, so a frame's grey g composites
// as B + g·K/255. And the worker that draws layers on its own thread, so that a frame
// never waits for one (a new view or model costs tens of milliseconds to draw).
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Core>

#include "evar/overlay/frame_compositor.hpp"

namespace evar::overlay::detail {

struct LayerKey {
  geometry::ProjectionMatrix P;
  const RoadmapModel* model = nullptr;
  RoadmapMode mode = RoadmapMode::Both;
  int width = 0, height = 0;
};

struct RoadmapLayer {
  LayerKey key;
  std::shared_ptr<const RoadmapModel> model;  ///< keeps key.model's address valid
  std::vector<std::uint8_t> b, k;             ///< premultiplied colour, transmittance (BGR rows)
  std::vector<Eigen::Vector3d> corners;       ///< the drawn model's bounding box

  /// Draws the same roadmap as a layer for `other` would: same model, mode and size, and a
  /// projection that moves no corner of the model's box by a quarter pixel (a still
  /// C-arm's readings jitter).
  bool serves(const LayerKey& other) const { return other.model == key.model && aligned_with(other); }
  /// Same mode, size and (within a quarter pixel) projection, whatever the model: drawn
  /// where `other`'s frame is, so it may stand in while `other`'s own layer is drawn.
  bool aligned_with(const LayerKey& other) const;
};

RoadmapLayer draw_roadmap_layer(const LayerKey& key, std::shared_ptr<const RoadmapModel> model, int supersample);

/// Draws the latest requested layer on its own thread; requests made while it draws
/// replace each other (only the newest matters).
class LayerWorker {
 public:
  explicit LayerWorker(int supersample);
  ~LayerWorker();
  LayerWorker(const LayerWorker&) = delete;
  LayerWorker& operator=(const LayerWorker&) = delete;

  /// Asks for a layer. A model, mode and size whose layer failed are not tried again for
  /// kRetryAfter (a failure that recurs must not keep a core busy).
  void request(const LayerKey& key, std::shared_ptr<const RoadmapModel> model);
  /// The newest finished layer not taken yet, or null. Every finished layer is handed out
  /// once; the compositor keeps the newest (the worker skips a request it already serves).
  std::shared_ptr<const RoadmapLayer> take();
  std::size_t renders() const;
  /// Why the layer for `key`'s model, mode and size could not be drawn; "" if it was not tried or worked.
  std::string error_for(const LayerKey& key) const;

  static constexpr std::chrono::seconds kRetryAfter{1};

 private:
  void run();

  int supersample_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::optional<std::pair<LayerKey, std::shared_ptr<const RoadmapModel>>> job_;
  std::shared_ptr<const RoadmapLayer> done_, last_;
  std::size_t renders_ = 0;
  struct Failure {
    const RoadmapModel* model;
    RoadmapMode mode;
    int width, height;
    std::chrono::steady_clock::time_point at;
    std::string what;
    std::shared_ptr<const RoadmapModel> keep;  // keeps the model address valid
  };
  std::optional<Failure> failure_;
  bool stop_ = false;
  std::thread thread_;  // last: starts after everything it uses
};

}  // namespace evar::overlay::detail
