#include "evar/node/output_sinks.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <iterator>
#include <stdexcept>

#include "evar/node/logging.hpp"

namespace evar::node {

std::optional<std::filesystem::path> set_aside_earlier(const std::filesystem::path& file) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) return std::nullopt;
  const auto written = std::filesystem::last_write_time(file, ec);
  const auto utc = std::chrono::system_clock::to_time_t(std::chrono::file_clock::to_sys(written));
  std::tm tm{};
  ::gmtime_r(&utc, &tm);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y%m%d-%H%M%SZ", &tm);
  const std::string stem = file.stem().string() + "-" + stamp, ext = file.extension().string();
  std::filesystem::path to = file.parent_path() / (stem + ext);
  for (int n = 1; std::filesystem::exists(to, ec); ++n) to = file.parent_path() / (stem + "-" + std::to_string(n) + ext);
  std::filesystem::rename(file, to, ec);
  if (ec) throw std::runtime_error("cannot set the earlier run's " + file.string() + " aside as " + to.string() + ": " + ec.message());
  return to;
}

VideoSink::VideoSink(std::filesystem::path path, double fps, std::uintmax_t max_bytes)
    : path_(std::move(path)), current_(path_), fps_(fps), max_bytes_(max_bytes),
      segment_bytes_(max_bytes == 0 ? 0 : std::max<std::uintmax_t>(max_bytes / 8, 1u << 20)) {
  // Segments an earlier run left in the same directory count against the budget (oldest
  // first, deleted first) and the numbering goes on after them, so none is overwritten.
  std::error_code ec;
  std::vector<std::pair<int, std::filesystem::path>> earlier;
  const std::string stem = path_.stem().string() + "-", ext = path_.extension().string();
  for (const auto& e : std::filesystem::directory_iterator(path_.parent_path().empty() ? "." : path_.parent_path(), ec)) {
    const std::string name = e.path().filename().string();
    if (name.size() != stem.size() + 4 + ext.size() || name.compare(0, stem.size(), stem) != 0 ||
        name.compare(stem.size() + 4, ext.size(), ext) != 0)
      continue;
    const std::string digits = name.substr(stem.size(), 4);
    if (!std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; })) continue;
    earlier.emplace_back(std::stoi(digits), e.path());
  }
  std::sort(earlier.begin(), earlier.end());
  for (const auto& [number, file] : earlier) {
    count_finished(file);
    next_number_ = number + 1;
  }
  // The segment an earlier run was writing when it stopped (a restarted service) is
  // finished under the next number rather than overwritten; if it cannot be renamed this
  // run writes to numbered segments from the start.
  if (std::filesystem::is_regular_file(path_, ec)) {
    const std::filesystem::path kept = numbered(next_number_++);
    std::filesystem::rename(path_, kept, ec);
    if (ec) {
      log().error("video: the earlier run's {} cannot be renamed to {} ({}); it is kept and this run writes to {}",
                  path_.string(), kept.string(), ec.message(), numbered(next_number_).string());
      current_ = numbered(next_number_);
    } else {
      log().info("video: the earlier run's unfinished segment is kept as {}", kept.string());
      count_finished(kept);
    }
  }
}

void VideoSink::count_finished(const std::filesystem::path& segment) {
  if (segment_bytes_ == 0) return;  // no budget: nothing to count or delete
  std::error_code ec;
  const std::uintmax_t bytes = std::filesystem::file_size(segment, ec);
  finished_.push_back({segment, ec ? 0 : bytes});
  finished_bytes_ += finished_.back().bytes;
}

std::filesystem::path VideoSink::numbered(int number) const {
  char digits[16];
  std::snprintf(digits, sizeof digits, "-%04d", number);
  return path_.parent_path() / (path_.stem().string() + digits + path_.extension().string());
}

void VideoSink::write(const ComposedFrame& frame) {
  if (frame.held) return;  // the file keeps the video's own timing; the gap is in the log
  // A full segment is finished when the next frame comes, so `path` always holds the newest.
  // What the disk refused then is said after this frame is written: no frame is lost to it.
  const std::string problem = segment_full_ ? finish_segment() : std::string();
  try {
    if (!writer_) writer_ = std::make_unique<overlay::VideoFileWriter>(current_, fps_, frame.image->width, frame.image->height);
    writer_->write(*frame.image);
  } catch (const std::exception& e) {
    if (problem.empty()) throw;
    throw std::runtime_error("video: " + problem + "; and then: " + e.what());
  }
  ++frames_;
  // The file's size, every 30 frames: a stat per second of video is plenty.
  if (segment_bytes_ > 0 && ++frames_in_segment_ % 30 == 0) {
    std::error_code ec;
    const std::uintmax_t bytes = std::filesystem::file_size(current_, ec);
    segment_full_ = !ec && bytes >= segment_bytes_;
  }
  if (!problem.empty()) throw std::runtime_error("video: " + problem);
}

std::string VideoSink::finish_segment() {
  segment_full_ = false;
  writer_->close();
  writer_.reset();
  frames_in_segment_ = 0;
  std::string problem;
  std::filesystem::path done = current_;
  if (current_ == path_) {
    std::error_code ec;
    std::filesystem::rename(path_, numbered(next_number_), ec);
    if (ec) {
      // Kept under its name; later segments go to numbered files so it is never reopened
      // (and truncated) as the current one.
      problem = "cannot rename " + path_.string() + " to " + numbered(next_number_).string() + ": " + ec.message();
      current_ = numbered(++next_number_);
    } else {
      done = numbered(next_number_++);
    }
  } else {
    current_ = numbered(++next_number_);
  }
  count_finished(done);
  std::error_code ec;
  while (!finished_.empty() && finished_bytes_ + segment_bytes_ > max_bytes_) {
    std::filesystem::remove(finished_.front().path, ec);
    if (ec && problem.empty())  // said once; the entry is dropped so the budget goes on with the rest
      problem = "cannot delete " + finished_.front().path.string() + " to stay within " +
                std::to_string(max_bytes_ >> 20) + " MiB: " + ec.message();
    else if (!ec)
      ++deleted_;
    finished_bytes_ -= finished_.front().bytes;
    finished_.pop_front();
  }
  return problem;
}

std::vector<std::filesystem::path> VideoSink::segments() const {
  std::vector<std::filesystem::path> out;
  for (const auto& s : finished_) out.push_back(s.path);
  return out;
}

void VideoSink::finish() {
  if (writer_) writer_->close();
}

SnapshotSink::SnapshotSink(std::filesystem::path directory, std::uintmax_t max_bytes)
    : directory_(std::move(directory)), max_bytes_(max_bytes) {
  std::filesystem::create_directories(directory_);
  // Pictures an earlier run left here count against the budget, oldest first; those the
  // clinician took (snapshot-*) are never deleted. New pictures never overwrite them.
  std::vector<std::pair<std::filesystem::file_time_type, Picture>> earlier;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(directory_, ec)) {
    if (!e.is_regular_file(ec) || e.path().extension() != ".png") continue;
    const std::uintmax_t size = e.file_size(ec);
    earlier.push_back({e.last_write_time(ec), {e.path(), ec ? 0 : size, e.path().filename().string().rfind("snapshot-", 0) == 0}});
  }
  std::sort(earlier.begin(), earlier.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  for (auto& [time, picture] : earlier) {
    bytes_ += picture.bytes;
    pictures_.push_back(std::move(picture));
  }
}

void SnapshotSink::save(const overlay::Image& image, const std::string& file, bool requested) {
  std::filesystem::path path = directory_ / file;
  std::error_code ec;
  for (int n = 1; std::filesystem::exists(path, ec); ++n)  // an earlier run's picture of the same name
    path = directory_ / (std::filesystem::path(file).stem().string() + "-" + std::to_string(n) + ".png");
  // Not synced: the output thread must not wait for the disk.
  overlay::write_png(path, image, base::Durability::Deferred);
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  pictures_.push_back({path, ec ? 0 : size, requested});
  bytes_ += pictures_.back().bytes;
  keep_within_budget();
}

void SnapshotSink::keep_within_budget() {
  if (max_bytes_ == 0) return;
  // The newest picture stays even when it alone is over the budget: it is the one just taken.
  // A picture the disk refuses to delete is said once and no longer counted, so the budget
  // goes on with the others instead of stopping at it every time.
  std::string problem;
  for (auto it = pictures_.begin(); bytes_ > max_bytes_ && it != pictures_.end() && std::next(it) != pictures_.end();) {
    if (it->requested) {
      ++it;
      continue;
    }
    std::error_code ec;
    std::filesystem::remove(it->path, ec);
    if (ec && problem.empty())
      problem = "cannot delete " + it->path.string() + " to stay within " + std::to_string(max_bytes_ >> 20) +
                " MiB: " + ec.message();
    if (!ec) ++deleted_;
    bytes_ -= it->bytes;
    it = pictures_.erase(it);
  }
  if (!problem.empty()) throw std::runtime_error("snapshots: " + problem);
}

std::vector<std::filesystem::path> SnapshotSink::kept() const {
  std::vector<std::filesystem::path> out;
  out.reserve(pictures_.size());
  for (const auto& p : pictures_) out.push_back(p.path);
  return out;
}

void SnapshotSink::write(const ComposedFrame& frame) {
  // Each picture is tried once. One that cannot be saved (disk full, folder gone) is given
  // up and said, but what this frame moves on still moves on: otherwise every later frame
  // would encode the same picture again on the output thread and fail again.
  std::string failure;
  const auto attempt = [&](const overlay::Image& image, const std::string& file, bool requested) {
    try {
      save(image, file, requested);
    } catch (const std::exception& e) {
      if (failure.empty()) failure = e.what();
    }
  };
  if (frame.held) {
    // Model pictures are of the video; a snapshot asked for now is of what the screen
    // shows, the held frame saying so.
    if (requested_.exchange(false)) attempt(*frame.image, "snapshot-held-" + std::to_string(frame.sequence) + ".png", true);
  } else {
    const std::uint64_t version = frame.model ? frame.model->version : 0;
    if (previous_ && version != previous_version_) {
      attempt(*previous_, "model-" + std::to_string(version) + "-before.png", false);
      after_ = version;
    }
    // "After" is the first frame drawn with the new model: the compositor may show the
    // previous one for a frame or two while it draws the new roadmap. A model superseded
    // before it was drawn has none (after_ moved on to the newer one above).
    if (after_ && frame.roadmap == overlay::RoadmapShown::Current) {
      attempt(*frame.image, "model-" + std::to_string(version) + "-after.png", false);
      after_.reset();
    }
    if (requested_.exchange(false)) attempt(*frame.image, "snapshot-" + std::to_string(frame.sequence) + ".png", true);
    previous_ = frame.image;
    previous_version_ = version;
  }
  if (!failure.empty()) throw std::runtime_error(failure);
}

IgtlSink::IgtlSink(overlay::IgtlServerOptions options, const geometry::Scene& scene, double mm_per_px, double max_fps)
    : server_(std::move(options)), mm_per_px_(mm_per_px), min_interval_ms_(max_fps > 0 ? 1000.0 / max_fps : 0.0) {
  for (const auto& v : scene.vessels) vessel_names_.push_back(v.name);
}

void IgtlSink::write(const ComposedFrame& frame) {
  const auto now = std::chrono::steady_clock::now();
  if (last_sent_ && std::chrono::duration<double, std::milli>(now - *last_sent_).count() < min_interval_ms_) return;
  last_sent_ = now;
  server_.send_image("evarnode", *frame.image, frame.detector_mm_per_px > 0.0 ? frame.detector_mm_per_px : mm_per_px_,
                     frame.device_time_ns);
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

}  // namespace evar::node
