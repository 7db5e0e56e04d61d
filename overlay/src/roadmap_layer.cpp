#include "roadmap_layer.hpp"

#include <algorithm>
#include <utility>

#include <Eigen/Geometry>

#include "perspective_projection.hpp"

namespace evar::overlay::detail {

bool RoadmapLayer::aligned_with(const LayerKey& other) const {
  if (other.mode != key.mode || other.width != key.width || other.height != key.height) return false;
  if (other.P == key.P) return true;
  if (corners.empty()) return false;  // nothing to measure the move by: only the same projection will do
  for (const Eigen::Vector3d& c : corners) {
    const Eigen::Vector3d pa = key.P * c.homogeneous(), pb = other.P * c.homogeneous();
    if (pa.z() <= 0 || pb.z() <= 0 || (pa.hnormalized() - pb.hnormalized()).norm() >= 0.25) return false;
  }
  return true;
}

RoadmapLayer draw_roadmap_layer(const LayerKey& key, std::shared_ptr<const RoadmapModel> model, int supersample) {
  RoadmapLayer layer;
  layer.key = key;
  Eigen::AlignedBox3d box;
  for (const auto* meshes : {&model->initial, &model->adapted})
    for (const auto& m : *meshes)
      for (Eigen::Index i = 0; i < m.V.rows(); ++i) box.extend(m.V.row(i).transpose());
  if (!box.isEmpty())
    for (int k = 0; k < 8; ++k) layer.corners.push_back(box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(k)));
  const PerspectiveProjection view(key.P, key.width, key.height);
  const Overlay overlay = roadmap_overlay(*model, key.mode);
  DrawOptions draw;
  draw.supersample = supersample;
  draw.label_font_scale = std::max(0.4, 0.55 * key.height / 1024.0);
  Image black = Image::filled(key.width, key.height, {0, 0, 0});
  Image white = Image::filled(key.width, key.height, {255, 255, 255});
  Image* const both[] = {&black, &white};
  composite(std::span<Image* const>(both), view, overlay, draw);
  layer.b = std::move(black.bgr);
  layer.k.resize(layer.b.size());
  for (std::size_t i = 0; i < layer.b.size(); ++i)
    layer.k[i] = static_cast<std::uint8_t>(std::max(0, int{white.bgr[i]} - int{layer.b[i]}));
  layer.model = std::move(model);
  return layer;
}

LayerWorker::LayerWorker(int supersample) : supersample_(supersample), thread_([this] { run(); }) {}

LayerWorker::~LayerWorker() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

namespace {
bool same_content(const LayerKey& key, const RoadmapModel* model, RoadmapMode mode, int width, int height) {
  return key.model == model && key.mode == mode && key.width == width && key.height == height;
}
}  // namespace

void LayerWorker::request(const LayerKey& key, std::shared_ptr<const RoadmapModel> model) {
  {
    std::lock_guard lock(mutex_);
    if (failure_ && same_content(key, failure_->model, failure_->mode, failure_->width, failure_->height) &&
        std::chrono::steady_clock::now() - failure_->at < kRetryAfter)
      return;
    job_.emplace(key, std::move(model));
  }
  wake_.notify_one();
}

std::shared_ptr<const RoadmapLayer> LayerWorker::take() {
  std::lock_guard lock(mutex_);
  return std::exchange(done_, nullptr);
}

std::size_t LayerWorker::renders() const {
  std::lock_guard lock(mutex_);
  return renders_;
}

std::string LayerWorker::error_for(const LayerKey& key) const {
  std::lock_guard lock(mutex_);
  if (failure_ && same_content(key, failure_->model, failure_->mode, failure_->width, failure_->height))
    return failure_->what;
  return {};
}

void LayerWorker::run() {
  std::unique_lock lock(mutex_);
  for (;;) {
    wake_.wait(lock, [&] { return stop_ || job_; });
    if (stop_) return;
    auto [key, model] = std::move(*job_);
    job_.reset();
    if (last_ && last_->serves(key)) continue;  // asked again while it was being drawn
    lock.unlock();
    std::shared_ptr<const RoadmapLayer> layer;
    std::string failed;
    try {
      layer = std::make_shared<const RoadmapLayer>(draw_roadmap_layer(key, model, supersample_));
    } catch (const std::exception& e) {
      failed = e.what();  // out of memory, or a model the drawing refuses (a non-finite marker)
    } catch (...) {
      failed = "unknown error";
    }
    lock.lock();
    if (!failed.empty()) {
      // The frames go on without this layer; the compositor says why (error_for).
      failure_ = Failure{key.model, key.mode, key.width, key.height, std::chrono::steady_clock::now(), failed, model};
      continue;
    }
    if (failure_ && same_content(key, failure_->model, failure_->mode, failure_->width, failure_->height)) failure_.reset();
    ++renders_;
    last_ = done_ = std::move(layer);
  }
}

}  // namespace evar::overlay::detail
