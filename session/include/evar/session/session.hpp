#pragma once
// A recorded session (format "evarnode-session", version 1; docs/SESSION_FORMAT.md): a
// directory with
//   session.json       format, version, the patient scene, the CT-to-C-arm registration,
//                      the device thickness and the streams below;
//   frames/index.csv   frame,timestamp_ns,source,file   (one row per frame, files 16-bit PNG
//                      relative to frames/);
//   carm.csv           timestamp_ns,primary_deg,secondary_deg,sid_mm,sod_mm,
//                      table_x_mm,table_y_mm,table_z_mm,fluoro_on,moving[,zoom_mode]
//                      (the C-arm geometry stream; the zoom mode's column when
//                      session.json lists the C-arm's zoom_modes);
//   optionally a ground truth (distorted vessels, true device, true 2D ostia per frame).
// Readers check everything and name the file and line of any problem; writers refuse what
// readers would (the same checks), so a written session always reads back.
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "evar/acquisition/carm_geometry_source.hpp"
#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/detector.hpp"
#include "evar/geometry/video_mapping.hpp"
#include "evar/geometry/zoom_mode.hpp"

namespace evar::session {

/// Timestamps are 0 <= t < 2^62 ns (146 years), so differences and a replay's loop offsets
/// cannot overflow 64 bits.
inline constexpr std::int64_t kMaxTimestampNs = std::int64_t{1} << 62;

struct FrameRecord {
  std::int64_t frame = 0;         ///< strictly increasing
  std::int64_t timestamp_ns = 0;  ///< acquisition time, non-decreasing, 0 <= t < kMaxTimestampNs
  std::string source;             ///< e.g. "fluoro", "dsa"; letters, digits, '_', '-' and '.'
  std::filesystem::path file;     ///< relative to frames/; no ".." component, no ',' or control character
};

/// One row of carm.csv: the C-arm's pose at a time on the host clock.
struct CArmSample : acquisition::CArmPose {
  std::int64_t timestamp_ns = 0;  ///< non-decreasing, 0 <= t < kMaxTimestampNs
};

/// The flat-panel detector every frame comes from (frames must have its size).
/// Where a true ostium projects in one frame (ground truth of simulated sessions).
struct OstiumTruth {
  std::int64_t frame = 0;
  std::string label;   ///< landmark label, e.g. "internal_iliac_right"
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
};

/// Optional ground truth: the distorted vessels, the true device, true 2D ostia per frame.
struct SessionTruth {
  std::filesystem::path scene;    ///< the distorted vessels as a scene.json (relative to the session)
  std::filesystem::path device;   ///< the true device, a Curve markup (CT LPS)
  std::filesystem::path ostia_2d; ///< CSV frame,label,u_px,v_px
  std::vector<OstiumTruth> ostia;
  /// The true CT-to-C-arm registration where the session's own (`Session::ct_to_carm`, what
  /// the node is given) is off by a residual; absent when they agree. Written as
  /// truth/registration.json (ground_truth.registration in session.json).
  std::optional<Eigen::Matrix4d> ct_to_carm;
};

struct Session {
  std::filesystem::path directory;
  std::filesystem::path scene;               ///< scene.json, relative to the session directory
  std::filesystem::path frames_index = "frames/index.csv";  ///< frame files are relative to its folder
  Eigen::Matrix4d ct_to_carm = Eigen::Matrix4d::Identity();  ///< registration at table position 0
  double device_thickness_mm = 0.9;
  geometry::DetectorSpec detector;
  /// Set: the frames are the C-arm's video output, the detector image shown in a rectangle
  /// of them (session.json "video_mapping"; docs/FORMATS.md). Frames then have its video size.
  std::optional<geometry::VideoMapping> video_mapping;
  /// The C-arm's zoom modes (session.json "zoom_modes"; geometry/zoom_mode.hpp): given,
  /// `detector` is the physical detector, each C-arm sample names the mode in force
  /// (CArmPose::zoom_mode, one of these) and a frame is the image of the mode at its time.
  /// The frames of every mode have one size (the video mapping's, or the modes' images').
  std::vector<geometry::ZoomMode> zoom_modes;
  std::vector<FrameRecord> frames;
  std::vector<CArmSample> carm;
  std::optional<SessionTruth> truth;
};

/// What breaks the format's rules for one frames/index.csv row ("" when nothing does): the
/// timestamp range, the source's characters, a file name inside frames/ that a CSV row holds.
std::string frame_record_problem(const FrameRecord& record);

/// What breaks the format's rules for one C-arm sample ("" when nothing does): finite
/// numbers, |primary| <= 180, |secondary| <= 90, 0 < SOD < SID <= 5000 mm, the timestamp
/// range. The reader, the writers and the recorder (which drops such samples) share it.
std::string carm_sample_problem(const CArmSample& sample);

/// Reads and checks a session directory (not the frame images: see read_session_frame).
/// Throws base::InputError "<file>:<line>: <field>: <problem>" (session.json, which has
/// no rows: "<file>: <field>: <problem>"). Files must stay inside the directory, symbolic
/// links followed.
Session read_session(const std::filesystem::path& directory);

/// A frame's image (CV_16UC1), checked to be a 16-bit single-channel PNG (by its signature,
/// whatever its name) of the frames' size, inside the session directory.
cv::Mat read_session_frame(const Session& session, std::size_t index);

/// A frame's detector image (CV_16UC1, the detector's size, or its zoom mode's image's): the
/// frame itself, or under a mapping (the video mapping, a mode's turn or flip) resampled out
/// of its image rectangle (geometry::detector_image).
cv::Mat read_detector_frame(const Session& session, std::size_t index);

/// The frames' size in pixels (cols, rows): the detector's, the zoom modes' images', or the
/// video mapping's.
std::pair<int, int> frame_size_px(const Session& session);

/// "" when the session's zoom modes fit it (each on the detector, the video mapping fitting
/// each mode's image, every mode's frames of one size), else what does not, naming the field.
std::string zoom_modes_problem(const Session& session);

/// The zoom mode a C-arm sample names, or null when the session has no zoom modes or does
/// not list it (a recording keeps the mode the C-arm said, listed or not).
const geometry::ZoomMode* zoom_mode_of(const Session& session, const CArmSample& sample);

/// Whether a sample's frames have a known field: the session has no zoom modes, or lists the
/// sample's. view_of throws std::invalid_argument, read_detector_frame and export an
/// InputError naming the frame, for those that do not.
bool zoom_known(const Session& session, const CArmSample& sample);

/// Writes session.json, registration.json, frames/index.csv, carm.csv (and the ostia CSV of
/// the ground truth, when present) into `directory` (created), and `images[i]` as
/// frames/<file of frames[i]> (CV_16UC1). Numbers are written so they read back
/// bit-exactly. std::invalid_argument for anything read_session would refuse.
void write_session(const std::filesystem::path& directory, const Session& session, const std::vector<cv::Mat>& images);

/// The same in two steps, for sessions too long to hold in memory: each frame's image as it
/// is made, then the files describing them (which check that every frame file exists).
void write_session_frame(const std::filesystem::path& directory, const FrameRecord& record, const cv::Mat& image);
void write_session_files(const std::filesystem::path& directory, const Session& session);

/// The C-arm view of a sample on the session's detector (geometry::view_of), or on its
/// zoom mode's image (geometry::zoom_view); std::invalid_argument when !zoom_known.
geometry::CArmView view_of(const Session& session, const CArmSample& sample);

/// CT → C-arm world at the sample's table position (geometry::patient_to_carm).
Eigen::Matrix4d patient_to_carm(const Session& session, const CArmSample& sample);

/// The C-arm sample in force at time t: the last one at or before t (the first if t is
/// earlier than all). nullptr when the session has none.
const CArmSample* carm_at(const Session& session, std::int64_t timestamp_ns);

struct ExportSummary {
  std::size_t frames = 0;
  int cols = 0, rows = 0;  ///< the sequence's image size (the detector's, or the zoom modes' images')
  /// Frames less than 1 ms after the one before, whose Timestamp was moved to 1 ms after it.
  std::size_t timestamps_nudged = 0;
};

/// Writes the session's frames as a PLUS toolkit sequence metafile (an uncompressed .mha
/// whose third axis is time, 2-D B-mode-like frames in MF orientation, the detector's pixel
/// spacing) that PLUS and 3D Slicer with the SlicerIGSIO extension load: per frame its
/// Timestamp (seconds from the first frame, in whole milliseconds, strictly increasing: the
/// importer keys frames by it), FrameNumber, ImageStatus, and the C-arm geometry in force
/// then (PrimaryAngleDeg, SecondaryAngleDeg, SidMm, SodMm, CArmMoving) as custom frame
/// fields. A frame not of the detector's size is an InputError naming it;
/// std::invalid_argument for an `mha` inside the session directory (it would be written
/// among the files being read). The frames are streamed, one in memory at a time, and the
/// file appears only when complete. Name it *.seq.mha. `progress(done, total)` after each frame.
ExportSummary export_plus_sequence(const Session& session, const std::filesystem::path& mha,
                                   const std::function<void(std::size_t, std::size_t)>& progress = {});

}  // namespace evar::session
