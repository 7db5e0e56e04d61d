#pragma once
// The node's outputs as OutputSinks: a video file, before/after snapshots of every model
// change (and on request), OpenIGTLink to 3D Slicer, and the bedside window.
#include <atomic>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "evar/node/live_node.hpp"
#include "evar/overlay/display_window.hpp"
#include "evar/overlay/igtl_server.hpp"
#include "evar/overlay/video_file_writer.hpp"

namespace evar::node {

/// A report an earlier run left at `file` (a restarted service writes into the same
/// directory) is renamed <stem>-<its UTC modification time><ext> (-1, -2, ... if taken),
/// so this run's report does not overwrite it. Returns the new name; none when there was no
/// such file. Throws std::runtime_error naming both files when the rename fails.
std::optional<std::filesystem::path> set_aside_earlier(const std::filesystem::path& file);

/// The composited video; the file is opened with the first frame's size. A node that runs
/// for hours would fill its disk (Motion-JPEG at 1024 x 1024 is about 10 GB an hour), so
/// with `max_bytes` the video is cut into segments of an eighth of it (at least 1 MiB): the
/// one being written is `path`, finished ones are renamed <stem>-0001<ext>, -0002, ... in
/// order, and the oldest are deleted while the finished ones and a segment to come would
/// exceed `max_bytes`; segments an earlier run left beside it count too, and numbering goes
/// on after them. 0 = one file, no limit.
class VideoSink final : public OutputSink {
 public:
  VideoSink(std::filesystem::path path, double fps, std::uintmax_t max_bytes = 0);
  std::string name() const override { return "video " + path_.string(); }
  /// Throws std::runtime_error naming the file when the disk refuses to rename a finished
  /// segment (it then stays under its name and the next ones are numbered) or to delete the
  /// oldest (it is no longer counted); the frame itself is written first.
  void write(const ComposedFrame& frame) override;
  void finish() override;
  std::size_t frames() const { return frames_; }  ///< written, all segments
  /// Finished segments still on disk, oldest first (the one being written is `path`).
  std::vector<std::filesystem::path> segments() const;
  std::uint64_t segments_deleted() const { return deleted_; }

 private:
  struct Segment {
    std::filesystem::path path;
    std::uintmax_t bytes;
  };
  /// Closes the current segment and keeps the video within its budget; what the disk
  /// refused (a rename, a delete), or "".
  std::string finish_segment();
  /// A finished segment counted against the budget (oldest first); nothing without one.
  void count_finished(const std::filesystem::path& segment);
  std::filesystem::path numbered(int number) const;

  std::filesystem::path path_, current_;  // asked for; being written (path_ unless a rename failed)
  double fps_;
  std::uintmax_t max_bytes_, segment_bytes_;
  std::unique_ptr<overlay::VideoFileWriter> writer_;
  std::size_t frames_ = 0, frames_in_segment_ = 0;
  bool segment_full_ = false;
  int next_number_ = 1;
  std::deque<Segment> finished_;
  std::uintmax_t finished_bytes_ = 0;
  std::uint64_t deleted_ = 0;
};

/// PNG pictures in a directory: at every model change the last frame before it
/// (model-N-before.png) and the first frame drawn with it (model-N-after.png); and the next
/// frame after request() (snapshot-SEQUENCE.png; snapshot-held-SEQUENCE.png while the last
/// frame is held for want of video). Held frames make no model pictures. A node that runs for days would fill its
/// disk with model-change pictures, so they are kept within `max_bytes` (0 = no limit):
/// past it the oldest go first. Requested snapshots are never deleted.
class SnapshotSink final : public OutputSink {
 public:
  explicit SnapshotSink(std::filesystem::path directory, std::uintmax_t max_bytes = 0);
  std::string name() const override { return "snapshots in " + directory_.string(); }
  void write(const ComposedFrame& frame) override;
  void request() { requested_ = true; }
  /// The pictures on disk, oldest first (deleted ones are not listed).
  std::vector<std::filesystem::path> kept() const;
  std::uint64_t deleted() const { return deleted_; }
  std::uintmax_t bytes() const { return bytes_; }  ///< of the pictures kept

 private:
  struct Picture {
    std::filesystem::path path;
    std::uintmax_t bytes = 0;
    bool requested = false;
  };
  void save(const overlay::Image& image, const std::string& file, bool requested);
  void keep_within_budget();
  std::filesystem::path directory_;
  std::uintmax_t max_bytes_;
  std::shared_ptr<const overlay::Image> previous_;  // held, not copied
  std::uint64_t previous_version_ = 0;
  std::optional<std::uint64_t> after_;  // the model whose first drawn frame is still to be saved
  std::atomic<bool> requested_{false};
  std::deque<Picture> pictures_;  // oldest first
  std::uintmax_t bytes_ = 0;
  std::uint64_t deleted_ = 0;
};

/// OpenIGTLink: frames as IMAGE "evarnode" (at most `max_fps`), each vessel's mesh as
/// POLYDATA under its name (the adapted one once there is a model), the landmarks as POINT
/// "landmarks". An image's spacing is the frame's at the detector (a zoom mode's own), or
/// `mm_per_px` for frames whose field is not known.
class IgtlSink final : public OutputSink {
 public:
  IgtlSink(overlay::IgtlServerOptions options, const geometry::Scene& scene, double mm_per_px, double max_fps);
  std::string name() const override { return "OpenIGTLink on port " + std::to_string(server_.port()); }
  void write(const ComposedFrame& frame) override;
  void model_changed(const PublishedModel& model) override;
  int port() const { return server_.port(); }
  overlay::IgtlServerStatistics statistics() const { return server_.statistics(); }

 private:
  overlay::IgtlServer server_;
  std::vector<std::string> vessel_names_;
  double mm_per_px_, min_interval_ms_;
  std::optional<std::chrono::steady_clock::time_point> last_sent_;
};

/// The bedside window. Keys: m cycles the roadmap mode, s takes a snapshot, f fullscreen,
/// q or Esc stop.
class WindowSink final : public OutputSink {
 public:
  struct Actions {
    std::function<void()> cycle_mode, snapshot, quit;
  };
  WindowSink(bool fullscreen, Actions actions) : fullscreen_(fullscreen), actions_(std::move(actions)) {}
  std::string name() const override { return "window"; }
  void write(const ComposedFrame& frame) override;

 private:
  bool fullscreen_;
  Actions actions_;
  std::unique_ptr<overlay::DisplayWindow> window_;  // made on the output thread
};

}  // namespace evar::node
