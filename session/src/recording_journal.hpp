#pragma once
// A recording's journal and how it becomes a session (docs/SESSION_FORMAT.md), shared by
// the recorder (session_recorder.cpp), which writes the journal as the streams arrive and
// assembles the session when it finishes, and crash recovery (recording_recovery.cpp),
// which reads it back. By file:
//   recording_journal.cpp   the journal's rows and settings, whole-frame checks, syncing
//   recording_assembly.cpp  streams to a session: both clocks mapped onto the host's
//   recording_recovery.cpp  a session from the journal of a recording that never finished
#include <Eigen/Core>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "evar/acquisition/clock_offset.hpp"
#include "evar/base/atomic_file.hpp"
#include "evar/acquisition/frame.hpp"
#include "evar/session/session.hpp"
#include "evar/session/session_recorder.hpp"

namespace evar::session::recording {

namespace fs = std::filesystem;
using acquisition::CArmState;
using acquisition::Frame;

// The journal of a recording in progress (docs/SESSION_FORMAT.md): what finish() needs, on
// disk as it arrives, so a recording that never reaches finish() can still become a session.
inline constexpr const char* kJournalFormat = "evarnode-recording-journal";
inline constexpr const char* kJournalFramesHeader =
    "frame,timestamp_ns,source,file,cols,rows,device_clock,device_time_ns,host_arrival_ns";
inline constexpr const char* kJournalCArmHeader =
    "device_time_ns,host_arrival_ns,primary_deg,secondary_deg,sid_mm,sod_mm,table_x_mm,table_y_mm,table_z_mm,fluoro_on,"
    "moving,zoom_mode";
// A journal of a recorder from before the zoom mode's column (recovered as mode 0).
inline constexpr const char* kJournalCArmHeaderWithoutZoom =
    "device_time_ns,host_arrival_ns,primary_deg,secondary_deg,sid_mm,sod_mm,table_x_mm,table_y_mm,table_z_mm,fluoro_on,"
    "moving";
// C-arm rows and the report reach the disk at least this often (frame rows with each frame).
inline constexpr auto kJournalPeriod = std::chrono::seconds(1);

inline fs::path journal_of(const fs::path& out) { return out / "journal"; }

// What the session files need besides the streams (journal/recording.json).
struct RecordingSettings {
  Eigen::Matrix4d ct_to_carm = Eigen::Matrix4d::Identity();
  double device_thickness_mm = 0.0;
  double pixel_spacing_mm = 0.0;  // at the detector, square pixels
  std::optional<geometry::VideoMapping> video_mapping;  // frames are the video output
  std::pair<int, int> detector_px{0, 0};                 // with a video mapping or zoom modes: the detector's size
  std::vector<geometry::ZoomMode> zoom_modes;            // the C-arm's, when given
  int zoom_mode = 0;                                     // not 0: every frame's, whatever the link says
};

// A recording's streams as they arrived, before they become a session.
struct RecordedStreams {
  std::vector<FrameRecord> frames;  // written, in frame order, timed live
  // Frames timed by a device clock: (frame number, clock sample), in frame order.
  std::vector<std::pair<std::int64_t, acquisition::ClockPair>> device_clock_frames;
  std::vector<CArmState> states;            // valid ones, in arrival order
  std::optional<std::pair<int, int>> size;  // the frames' (cols, rows)
};

inline std::int64_t ns_of(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
}

/// The session format's C-arm sample of a state, at `timestamp_ns` on the host clock.
CArmSample sample_of(const CArmState& s, std::int64_t timestamp_ns);

// Frames timed by a device clock were stamped live with the offset known so far; with the
// whole recording at hand, each gets the offset of the frames around it, later ones too.
// `frames` is in frame-number order and stays so.
void map_frames_offline(const std::vector<std::pair<std::int64_t, acquisition::ClockPair>>& device_clock_frames,
                        std::vector<FrameRecord>& frames);

// The session a recording makes, the same from memory (finish) and from the journal
// (recovery). C-arm states whose time on the host clock falls outside the format's range
// are left out and counted in `dropped`; those whose zoom mode the settings do not list are
// counted in `zoom_unlisted` (kept with it, or as the detector's without zoom modes).
Session assemble(const fs::path& out, const RecordingSettings& settings, const RecordedStreams& streams,
                 std::uint64_t& dropped, std::uint64_t& zoom_unlisted);

/// One row of the journal's frames.csv and carm.csv.
std::string journal_frame_row(const FrameRecord& r, const Frame& f);
std::string journal_carm_row(const CArmState& s);

// Through an AtomicFile, so a recorder killed while writing leaves the last whole report.
void write_json_file(const fs::path& file, const nlohmann::ordered_json& j,
                     base::Durability durability = base::Durability::Synced);

/// journal/recording.json; InputError naming the field when it is not one.
RecordingSettings read_settings(const fs::path& file);

// Whether a frame's PNG was written whole: its header says the frame's size and it ends with
// the IEND chunk (a recorder killed while writing leaves the file cut short).
bool whole_png(const fs::path& file, int cols, int rows);

// The session's files, its frames among them, and their directories on the disk (syncfs of
// their filesystem; fsync of the session's own files where that fails) before the journal
// that could rebuild them goes: a power cut right after finishing must not leave them
// empty. Frames are not synced one by one as they are written (an hour of them would take
// minutes).
void sync_session_files(const fs::path& dir);

}  // namespace evar::session::recording
