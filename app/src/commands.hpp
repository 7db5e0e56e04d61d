#pragma once
// The subcommands, each parsed by cli.cpp into its options struct.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "evar/geometry/mesh_io.hpp"
#include "source_factory.hpp"

namespace evar::app {

struct DeformCommand {
  std::filesystem::path scene, device, out;
  bool skeleton = true;
  bool preview = true;
  std::string solver = "default";
  double tolerance_mm = 0.01;
  int max_iterations = 500;
  int containment_rounds = 3;
  double tether_mm = 50.0;
  bool coarse_rotations = true;
  bool ordered_pairing = true;
  double proxy_edge_mm = 1.4;
  /// The pelvis's displacement against the registered models (scene LPS mm), measured
  /// otherwise (a bony 2D/3D registration); empty: none (deform/pelvis_shift.hpp).
  std::vector<double> pelvis_shift_mm;
  /// Exit kExitDeviceOutside when the deformed vessels leave the device outside by more
  /// than the warning threshold (the outputs are written either way).
  bool strict = false;
};
/// `deform --strict`: the result was written, but leaves the device outside the vessels.
inline constexpr int kExitDeviceOutside = 4;
int run_deform(const DeformCommand& cmd);

struct SceneCommand {
  std::filesystem::path surface, centerlines, ostia, out;
  std::string axes;
  double device_thickness_mm = 0.89;
  bool picture = true;
};
int run_scene(const SceneCommand& cmd);

struct ProxiesCommand {
  std::filesystem::path scene;
  double proxy_edge_mm = 1.4;  // as deform's default
};
int run_proxies(const ProxiesCommand& cmd);

struct ArapCommand {
  std::filesystem::path mesh, constraints, out, report;
  std::optional<int> iterations;
  std::optional<double> tolerance_mm;
  std::string solver = "default";
  bool anderson = true;
};
int run_arap(const ArapCommand& cmd);

/// The mesh format named by a --format option ("stl", "ply" or "obj"; binary where the format has one).
geometry::MeshFormat mesh_format_option(const std::string& name);

/// A synthetic scene drawn by a seed and written to a directory: `example` and `sim patient`.
struct SyntheticSceneCommand {
  std::filesystem::path out;
  unsigned long long seed = 1;
  std::string format = "stl";
  int aorta_vertices = 7500;
  int iliac_vertices = 3500;
  std::string difficulty = "mild";  ///< sim patient only (sim::parse_difficulty)
  std::string physics = "beam";     ///< sim patient only (sim::parse_truth_physics)
};
int run_example(const SyntheticSceneCommand& cmd);
int run_sim_patient(const SyntheticSceneCommand& cmd);

struct SimSessionCommand {
  std::filesystem::path out;
  unsigned long long seed = 1;
  int detector_px = 1024;
  double fluoro_seconds = 4.0;
  double fluoro_fps = 15.0;
  std::string difficulty = "mild";
  std::string physics = "beam";
  std::filesystem::path video_out;  ///< a video mapping file: frames as the C-arm monitor shows them
  bool zoom_change = false;         ///< two zoom modes, switched in the last fluoroscopy run
  bool progress = true;
};
int run_sim_session(const SimSessionCommand& cmd);

struct ReplayCommand {
  std::filesystem::path session, report;
  double speed = 1.0;
  bool fast = false;
  bool preload = false;  ///< decode every frame before playing (session::ReplayOptions::preload)
  int loops = 1;
  bool progress = true;
  std::string serve_gige;       ///< serial of a GigE Vision camera that shows the frames
  std::string gige_interface = "lo";
  std::string serve_carm;       ///< path of a link to a pty that carries the C-arm states
};
int run_replay(const ReplayCommand& cmd);

struct ExportCommand {
  std::filesystem::path session, out;
  bool progress = true;
};
int run_export(const ExportCommand& cmd);

struct DevicesCommand {
  bool json = false;
  std::string usb;  ///< VID:PID[:SERIAL]: only the matching USB devices
};
int run_devices(const DevicesCommand& cmd);

struct RecordCommand {
  FrameSourceSpec frames;             ///< the GigE camera or V4L2 grabber
  std::string carm;                   ///< serial:PATH[,baud=N,...] or usb:VID:PID[:SERIAL]
  std::filesystem::path out, scene, registration;
  double pixel_spacing_mm = 0.0;
  std::filesystem::path video_mapping;  ///< the frames are a C-arm's video output (with detector_px)
  std::vector<int> detector_px;         ///< cols and rows of the detector behind the video output
  std::filesystem::path zoom_modes;     ///< a node.json whose detector and zoom_modes the C-arm has
  std::optional<double> device_thickness_mm;
  std::optional<double> seconds;
  std::optional<int> frames_to_write;
  std::filesystem::path recover;      ///< instead of recording: the unfinished recording to make a session of
};
int run_record(const RecordCommand& cmd);

/// Options shared by segment and reconstruct.
struct SegmentParams {
  double diameter_mm = 0.89;             ///< device diameter (0.035" guidewire), for its shadow width
  std::optional<double> width_px;        ///< shadow width, when no geometry is known
  std::vector<double> seed;              ///< u v of a click on the tip
  double min_contrast = 0.25;
};

struct SegmentCommand {
  std::filesystem::path image, geometry, out, overlay;
  SegmentParams params;
};
int run_segment(const SegmentCommand& cmd);

struct ReconstructCommand {
  std::vector<std::filesystem::path> images, geometries;
  std::filesystem::path registration, out, report, overlay_prefix;
  SegmentParams params;
  double min_separation_deg = 20.0;
};
int run_reconstruct(const ReconstructCommand& cmd);

struct EvalCommand {
  std::vector<std::filesystem::path> sessions;
  std::filesystem::path out;
  bool progress = true;
  bool pelvis = true;  ///< find the pelvis in the fluoroscopy where the scene has its bones (as the node)
};
int run_eval(const EvalCommand& cmd);

struct RunCommand {
  std::filesystem::path config, replay, out = "out/run";
  std::string video = "overlay.avi";
  bool no_video = false;
  std::uintmax_t video_budget_mb = 16384;    ///< the video kept within this, oldest segments deleted (0 = no limit)
  std::uintmax_t snapshot_budget_mb = 1024;  ///< model-change pictures kept within this (0 = no limit)
  bool igtl = true;
  int igtl_port = 18944;
  std::string igtl_bind = "127.0.0.1";
  bool display = false, fullscreen = false;
  std::string mode = "both";
  double speed = 1.0;
  bool fast = false;
  bool preload = false;  ///< decode every frame before playing (session::ReplayOptions::preload)
  bool pelvis = true;   ///< find the pelvis in the fluoroscopy where the scene has its bones
  int loops = 1;
  std::optional<double> seconds;
  bool progress = true;
};
int run_node(const RunCommand& cmd);

struct CalibrateVideoCommand {
  std::vector<std::filesystem::path> frames;
  std::filesystem::path out, picture, node;
  int rotation_deg = 0;
  bool mirror = false;
  std::vector<int> detector_px;  ///< empty, or cols and rows: the mapping is checked against it
};
int run_calibrate_video(const CalibrateVideoCommand& cmd);

struct ProjectCommand {
  std::filesystem::path geometry, registration, points, out;
};
int run_project(const ProjectCommand& cmd);

}  // namespace evar::app
