#include "output_sinks.hpp"

namespace evar::app {

void VideoSink::write(const ComposedFrame& frame) {
  if (!writer_) writer_ = std::make_unique<overlay::VideoFileWriter>(path_, fps_, frame.image->width, frame.image->height);
  writer_->write(*frame.image);
}

void VideoSink::finish() {
  if (writer_) writer_->close();
}

SnapshotSink::SnapshotSink(std::filesystem::path directory) : directory_(std::move(directory)) {
  std::filesystem::create_directories(directory_);
}

void SnapshotSink::save(const overlay::Image& image, const std::string& file) {
  overlay::write_png(directory_ / file, image);
  written_.push_back(directory_ / file);
}

void SnapshotSink::write(const ComposedFrame& frame) {
  const std::uint64_t version = frame.model ? frame.model->version : 0;
  if (previous_ && version != previous_version_) {
    save(*previous_, "model-" + std::to_string(version) + "-before.png");
    after_ = version;
  }
  // "After" is the first frame drawn with the new model: the compositor may show the
  // previous one for a frame or two while it draws the new roadmap. A model superseded
  // before it was drawn has none (after_ moved on to the newer one above).
  if (after_ && frame.roadmap == overlay::RoadmapShown::Current) {
    save(*frame.image, "model-" + std::to_string(version) + "-after.png");
    after_.reset();
  }
  if (requested_.exchange(false)) save(*frame.image, "snapshot-" + std::to_string(frame.sequence) + ".png");
  previous_ = frame.image;
  previous_version_ = version;
}

IgtlSink::IgtlSink(overlay::IgtlServerOptions options, const geometry::Scene& scene, double mm_per_px, double max_fps)
    : server_(std::move(options)), mm_per_px_(mm_per_px), min_interval_ms_(max_fps > 0 ? 1000.0 / max_fps : 0.0) {
  for (const auto& v : scene.vessels) vessel_names_.push_back(v.name);
}

void IgtlSink::write(const ComposedFrame& frame) {
  const auto now = std::chrono::steady_clock::now();
  if (last_sent_ && std::chrono::duration<double, std::milli>(now - *last_sent_).count() < min_interval_ms_) return;
  last_sent_ = now;
  server_.send_image("evarnode", *frame.image, mm_per_px_, frame.device_time_ns);
}

void IgtlSink::model_changed(const PublishedModel& model) {
  const auto& r = *model.roadmap;
  const bool adapted = !r.adapted.empty();
  for (std::size_t i = 0; i < vessel_names_.size(); ++i)
    server_.send_mesh(vessel_names_[i], adapted ? r.adapted[i] : r.initial[i]);
  server_.send_points("landmarks", adapted ? r.adapted_landmarks : r.initial_landmarks);
}

void WindowSink::write(const ComposedFrame& frame) {
  if (!window_) window_ = std::make_unique<overlay::DisplayWindow>("evarnode", fullscreen_);
  switch (window_->show(*frame.image)) {
    case overlay::WindowKey::CycleMode:
      if (actions_.cycle_mode) actions_.cycle_mode();
      break;
    case overlay::WindowKey::Snapshot:
      if (actions_.snapshot) actions_.snapshot();
      break;
    case overlay::WindowKey::Quit:
      if (actions_.quit) actions_.quit();
      break;
    case overlay::WindowKey::None: break;
  }
}

}  // namespace evar::app
