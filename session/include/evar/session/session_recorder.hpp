#pragma once
// Records what a frame source and a C-arm geometry source deliver as a session
// (docs/SESSION_FORMAT.md) that `evarnode replay` and every reader of the format take: the
// frames as 16-bit PNG written by a writer thread as they come (Mono8 scaled by 257, Mono12
// by 16, so grey levels keep their meaning), the C-arm states on the frames' clock (the
// C-arm's own clock mapped onto the host's through a minimum-delay offset estimate), the
// patient scene copied in, and a JSON report of what arrived and what was lost.
//
// While it records, a journal (out/journal/) holds what finish() needs to write the session
// files: a row per frame once its PNG is written, the raw C-arm states (flushed about every
// second) and the settings; the report is rewritten every second too. A recording that never
// reaches finish() (SIGKILL, out of memory, a crash) becomes a session with
// recover_recording() (`evarnode record --recover OUT`). Rows are handed to the kernel, not
// synced: a power cut can lose the last seconds the kernel had not yet written.
#include <Eigen/Core>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "evar/acquisition/carm_geometry_source.hpp"
#include "evar/acquisition/frame_source.hpp"
#include "evar/session/session.hpp"

namespace evar::session {

struct RecorderOptions {
  std::filesystem::path out;                  ///< the session directory; must not exist or be empty
  std::filesystem::path scene;                ///< the patient's scene.json, copied into out/patient/
  Eigen::Matrix4d ct_to_carm = Eigen::Matrix4d::Identity();  ///< the registration at table 0
  double pixel_spacing_mm = 0.0;              ///< at the detector (square pixels)
  /// Set: the frames are a C-arm's video output, the detector image shown in this mapping's
  /// rectangle; frames must have its video size and the session carries it (session.json
  /// "video_mapping"). `detector_px` is then the detector's cols and rows.
  std::optional<geometry::VideoMapping> video_mapping;
  std::pair<int, int> detector_px{0, 0};
  /// Set: the C-arm's zoom modes (session.json "zoom_modes"): `detector_px` and
  /// `pixel_spacing_mm` are then the physical detector's, each C-arm state's mode is recorded
  /// (states in a mode not listed are not), and frames have the modes' one frame size.
  /// Without them a mode the link says is not kept (RecorderStatistics::carm_zoom_unlisted).
  std::vector<geometry::ZoomMode> zoom_modes;
  /// Not 0: every frame is in this mode of `zoom_modes`, whatever the link says (node.json's
  /// "zoom_mode"); 0: the link's, or the only mode listed when the link says none.
  int zoom_mode = 0;
  std::optional<double> device_thickness_mm;  ///< default: the scene's
  std::string source = "fluoro";              ///< frames/index.csv source column
  std::size_t max_queued_frames = 64;         ///< waiting for the disk; beyond, frames are not recorded
};

/// received = written + not_recorded + refused + write_failed (+ still queued, while recording).
struct RecorderStatistics {
  std::uint64_t frames_received = 0, frames_written = 0;
  std::uint64_t frames_not_recorded = 0;  ///< the disk fell behind (queue full)
  std::uint64_t frames_refused = 0;       ///< a size other than the first frame's
  std::uint64_t frames_write_failed = 0;  ///< their PNG could not be written (disk full, ...)
  std::uint64_t carm_samples = 0;         ///< recorded
  std::uint64_t carm_refused = 0;         ///< not recorded: values the format refuses (carm_sample_problem)
  /// C-arm states whose zoom mode the recording's zoom_modes do not list: without zoom modes
  /// recorded as the detector's (the mode dropped), with them recorded as said (their frames
  /// then have no known field: session::zoom_known).
  std::uint64_t carm_zoom_unlisted = 0;
  acquisition::StreamState video = acquisition::StreamState::Stopped, carm = acquisition::StreamState::Stopped;
  std::string video_reason, carm_reason;  ///< the sources' last words
  std::uint64_t carm_notices = 0;         ///< the C-arm link's news (bad frames, a C-arm warning)
  std::vector<std::string> recent_carm_notices;  ///< the last kRecentNotices of them, oldest first
  static constexpr std::size_t kRecentNotices = 32;
  std::string last_error;                 ///< the last frame or sample that could not be recorded, named
  double seconds = 0.0;                   ///< since start()
};

class SessionRecorder {
 public:
  /// Checks the options and loads the scene (base::InputError naming the file); the
  /// sources are only borrowed and must outlive the recorder.
  SessionRecorder(RecorderOptions options, acquisition::FrameSource& frames, acquisition::CArmGeometrySource& carm);
  ~SessionRecorder();
  SessionRecorder(const SessionRecorder&) = delete;
  SessionRecorder& operator=(const SessionRecorder&) = delete;

  /// Starts both sources and the writer.
  void start();
  RecorderStatistics statistics() const;
  /// Stops the sources, writes what is queued and the session files and report
  /// (out/record_report.json), and removes the journal. Throws std::runtime_error when no
  /// frame arrived (the directory then holds the report and the copied scene) or no C-arm
  /// sample did (the session is written with its frames and no geometry, so nothing
  /// recorded is lost). When the session files cannot be written (disk full), the report
  /// says so, the journal stays for recover_recording(), and the error is rethrown.
  Session finish();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// What recover_recording() made of a journal.
struct RecoveredRecording {
  Session session;
  std::uint64_t frames_journaled = 0;  ///< rows in the frame journal
  std::uint64_t frames_lost = 0;       ///< of those, PNG missing, cut short or of another size (left out)
  std::uint64_t carm_samples = 0;      ///< in the session
  bool cut_row_skipped = false;        ///< a journal row the end of the recorder cut in half
  std::uint64_t partial_files_removed = 0;  ///< files the kill left half written before their rename
};

/// Turns an unfinished recording (the --out of a recorder that never reached finish()) into
/// a session from its journal: every frame whose PNG is whole, every C-arm state, timed as
/// finish() would; the report gains a "recovered" part; the journal and the partial files
/// of writes the kill interrupted (base/atomic_file.hpp) are removed.
/// base::InputError naming the file and line for a directory that holds no journal or
/// a damaged one; std::runtime_error, as finish(), when it holds no frame or no C-arm
/// sample (the latter after writing the session).
RecoveredRecording recover_recording(const std::filesystem::path& directory);

/// C-arm states on the host's steady clock: per sample, C-arm time plus the smallest
/// arrival delay among the samples within ±30 s of C-arm time around it; a clock that goes
/// back or jumps ahead by more than a second starts a new stretch. Timestamps never decrease.
std::vector<CArmSample> carm_on_host_clock(const std::vector<acquisition::CArmState>& states);

/// A grabbed frame as the session's 16-bit image (Mono8 ×257, Mono12 ×16, Mono16 as is).
cv::Mat to_session_image(const acquisition::Frame& frame);

}  // namespace evar::session
