#pragma once
// A recorded session (format "evarnode-session", version 1; docs/SESSION_FORMAT.md): a
// directory with
//   session.json       format, version, the patient scene, the CT-to-C-arm registration,
//                      the device thickness and the streams below;
//   frames/index.csv   frame,timestamp_ns,source,file   (one row per frame, files 16-bit PNG
//                      relative to frames/);
//   carm.csv           timestamp_ns,primary_deg,secondary_deg,sid_mm,sod_mm,
//                      table_x_mm,table_y_mm,table_z_mm,fluoro_on,moving
//                      (the C-arm geometry stream).
// Readers check everything and name the file and line of any problem.
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace evar::sim {

struct FrameRecord {
  std::int64_t frame = 0;         ///< strictly increasing
  std::int64_t timestamp_ns = 0;  ///< acquisition time, non-decreasing
  std::string source;             ///< e.g. "fluoro", "dsa"; letters, digits, '_' and '-'
  std::filesystem::path file;     ///< relative to frames/
};

struct CArmSample {
  std::int64_t timestamp_ns = 0;  ///< non-decreasing
  double primary_deg = 0.0, secondary_deg = 0.0;  ///< DICOM conventions (+ LAO, + CRA)
  double sid_mm = 0.0, sod_mm = 0.0;
  Eigen::Vector3d table_mm = Eigen::Vector3d::Zero();
  bool fluoro_on = false;         ///< the beam is on
  bool moving = false;            ///< the C-arm is moving (geometry not settled)
};

struct Session {
  std::filesystem::path directory;
  std::filesystem::path scene;               ///< scene.json, relative to the session directory
  Eigen::Matrix4d ct_to_carm = Eigen::Matrix4d::Identity();
  double device_thickness_mm = 0.9;
  std::vector<FrameRecord> frames;
  std::vector<CArmSample> carm;
};

/// Reads and checks a session directory (not the frame images: see read_session_frame).
/// Throws geometry::InputError "<file>:<line>: <field>: <problem>".
Session read_session(const std::filesystem::path& directory);

/// A frame's image (CV_16UC1), checked to be a 16-bit single-channel PNG.
cv::Mat read_session_frame(const Session& session, std::size_t index);

/// Writes session.json, frames/index.csv and carm.csv into `directory` (created), and
/// `images[i]` as frames/<file of frames[i]> (CV_16UC1). Numbers are written so they read
/// back bit-exactly. std::invalid_argument for inconsistent input.
void write_session(const std::filesystem::path& directory, const Session& session, const std::vector<cv::Mat>& images);

/// The C-arm sample in force at time t: the last one at or before t (the first if t is
/// earlier than all). nullptr when the session has none.
const CArmSample* carm_at(const Session& session, std::int64_t timestamp_ns);

/// Writes the session's frames as a PLUS toolkit sequence metafile (an uncompressed .mha
/// whose third axis is time) that 3D Slicer's Sequences module loads: per frame its
/// Timestamp (seconds from the first frame), FrameNumber, ImageStatus, and the C-arm
/// geometry in force then (PrimaryAngleDeg, SecondaryAngleDeg, SidMm, SodMm, CArmMoving) as
/// custom frame fields. All frames must share one size. Name it *.seq.mha for Slicer.
void export_plus_sequence(const Session& session, const std::filesystem::path& mha);

}  // namespace evar::sim
