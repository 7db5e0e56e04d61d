#pragma once
// node.json (format "evarnode-node", version 1): what `evarnode run` needs for live
// sources. Paths are relative to the file. docs/FORMATS.md describes it.
//
// {
//   "format": "evarnode-node", "version": 1,
//   "scene": "patient/scene.json", "registration": "registration.json",
//   "detector": {"cols": 1024, "rows": 1024, "row_spacing_mm": 0.3, "col_spacing_mm": 0.3},
//   "frames": {"camera": "", "pixel_format": "mono16", "packet_socket": false, "fps": 30}   or   {"v4l2": "/dev/video0", "v4l2_format": "Y16"},
//   "carm": "serial:/dev/ttyUSB0,baud=115200",
//   "fps": 30,
//   "device_diameter_mm": 0.89, "min_contrast": 0.25, "min_separation_deg": 20,
//   "geometry_stale_ms": 250, "max_view_gap_s": 120, "pelvis": true,
//   "video_mapping": {"format": "evarnode-video-mapping", ...}   or   "mapping.json",
//   "zoom_modes": [{"mode": 1, "name": "48 cm", "field_of_view_dimensions_mm": [384, 384], ...}],
//   "zoom_mode": 1
// }
// Everything but format and version is optional for replays (the session has the patient,
// the registration and the detector).
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "evar/geometry/detector.hpp"
#include "evar/geometry/video_mapping.hpp"
#include "evar/geometry/zoom_mode.hpp"
#include "source_factory.hpp"

namespace evar::app {

struct NodeConfig {
  std::filesystem::path file;
  std::optional<std::filesystem::path> scene, registration;
  std::optional<geometry::DetectorSpec> detector;
  /// The frames are the C-arm's video output (the monitor's picture): where the detector
  /// image lies in them. Given inline or as a file (`evarnode calibrate-video` writes one).
  std::optional<geometry::VideoMapping> video_mapping;
  /// The C-arm's zoom modes (geometry/zoom_mode.hpp); `detector` is then the physical one.
  std::vector<geometry::ZoomMode> zoom_modes;
  /// Not 0: every frame is in this mode whatever the C-arm link says.
  int zoom_mode = 0;
  std::optional<FrameSourceSpec> frames;
  std::optional<std::string> carm;
  std::optional<double> fps;
  double device_diameter_mm = 0.89;
  double min_contrast = 0.25;
  double min_separation_deg = 20.0;
  /// C-arm geometry older than this at a frame is stale (default 250 ms: a link that
  /// streams; longer for a C-arm that reports only when something changes).
  std::optional<double> geometry_stale_ms;
  /// Two views further apart in time than this are not paired (the device has moved on).
  double max_view_gap_s = 120.0;
  /// Find the pelvis in the fluoroscopy where the scene has its bones, and move the models with it.
  bool pelvis = true;
};

/// Throws base::InputError "<file>: <field>: <problem>".
NodeConfig read_node_config(const std::filesystem::path& path);

}  // namespace evar::app
