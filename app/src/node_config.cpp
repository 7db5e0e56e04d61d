#include "node_config.hpp"

#include <nlohmann/json.hpp>

#include "evar/geometry/image_header.hpp"
#include "evar/base/input_error.hpp"
#include "evar/geometry/json_fields.hpp"

namespace evar::app {

namespace {

using geometry::detail::bad_field;
using geometry::detail::number_field;

std::string text(const nlohmann::json& j, const std::filesystem::path& file, const std::string& field) {
  if (!j.is_string()) bad_field(file, field, "expected a string");
  return j.get<std::string>();
}

}  // namespace

NodeConfig read_node_config(const std::filesystem::path& path) {
  const nlohmann::json j = geometry::detail::parse_json_file(path);
  if (!j.is_object()) bad_field(path, "(file)", "expected a JSON object");
  if (!j.contains("format") || j["format"] != "evarnode-node") bad_field(path, "format", "expected \"evarnode-node\"");
  if (!j.contains("version") || j["version"] != 1) bad_field(path, "version", "expected 1");
  NodeConfig c;
  c.file = path;
  const auto dir = path.parent_path();
  for (const auto& [key, value] : j.items()) {
    if (key == "format" || key == "version") continue;
    if (key == "scene") c.scene = dir / text(value, path, key);
    else if (key == "registration") c.registration = dir / text(value, path, key);
    else if (key == "detector") {
      if (!value.is_object()) bad_field(path, key, "expected an object");
      geometry::DetectorSpec d;
      for (const char* f : {"cols", "rows", "row_spacing_mm", "col_spacing_mm"})
        if (!value.contains(f)) bad_field(path, key + "." + f, "missing");
      d.cols = static_cast<int>(number_field(path, value["cols"], "detector.cols", 1, 16384, "px"));
      d.rows = static_cast<int>(number_field(path, value["rows"], "detector.rows", 1, 16384, "px"));
      d.row_spacing_mm = number_field(path, value["row_spacing_mm"], "detector.row_spacing_mm", 1e-3, 10, "mm");
      d.col_spacing_mm = number_field(path, value["col_spacing_mm"], "detector.col_spacing_mm", 1e-3, 10, "mm");
      if (std::int64_t{d.cols} * d.rows > geometry::kMaxImagePixels)
        bad_field(path, key, std::to_string(d.cols) + " x " + std::to_string(d.rows) + " pixels; at most " +
                                 std::to_string(geometry::kMaxImagePixels) + " in all");
      c.detector = d;
    } else if (key == "frames") {
      if (!value.is_object()) bad_field(path, key, "expected an object");
      FrameSourceSpec s;
      for (const auto& [k, v] : value.items()) {
        const std::string field = "frames." + k;
        if (k == "camera") s.camera = text(v, path, field);
        else if (k == "pixel_format") {
          s.pixel_format = text(v, path, field);
          if (s.pixel_format != "mono8" && s.pixel_format != "mono12" && s.pixel_format != "mono16")
            bad_field(path, field, "expected mono8, mono12 or mono16");
        } else if (k == "v4l2") s.v4l2 = text(v, path, field);
        else if (k == "v4l2_format") s.v4l2_format = text(v, path, field);
        else if (k == "width") s.width = static_cast<int>(number_field(path, v, field, 16, 16384, "px"));
        else if (k == "height") s.height = static_cast<int>(number_field(path, v, field, 16, 16384, "px"));
        else if (k == "fps") s.fps = number_field(path, v, field, 0.1, 1000, "frames per second");
        else if (k == "packet_socket") {
          if (!v.is_boolean()) bad_field(path, field, "expected true or false");
          s.packet_socket = v.get<bool>();
        } else bad_field(path, field, "unknown setting");
      }
      if (s.width && s.height && std::int64_t{*s.width} * *s.height > geometry::kMaxImagePixels)
        bad_field(path, "frames", std::to_string(*s.width) + " x " + std::to_string(*s.height) + " pixels; at most " +
                                      std::to_string(geometry::kMaxImagePixels) + " in all");
      c.frames = s;
    } else if (key == "carm") c.carm = text(value, path, key);
    else if (key == "fps") c.fps = number_field(path, value, key, 0.1, 1000, "frames per second");
    else if (key == "device_diameter_mm") c.device_diameter_mm = number_field(path, value, key, 0.1, 10, "mm");
    else if (key == "min_contrast") c.min_contrast = number_field(path, value, key, 0, 5, "");
    else if (key == "min_separation_deg") c.min_separation_deg = number_field(path, value, key, 5, 80, "degrees");
    else if (key == "max_view_gap_s") c.max_view_gap_s = number_field(path, value, key, 1, 3600, "s");
    else if (key == "video_mapping") {
      if (value.is_string()) {
        try {
          c.video_mapping = geometry::read_video_mapping(dir / value.get<std::string>());
        } catch (const base::InputError& e) {
          bad_field(path, key, std::string("the mapping it names: ") + e.what());
        }
      }
      else if (value.is_object()) c.video_mapping = geometry::parse_video_mapping(value, path, "video_mapping.");
      else bad_field(path, key, "expected the mapping's object or the name of its file");
    } else if (key == "pelvis") {
      if (!value.is_boolean()) bad_field(path, key, "expected true (find the pelvis in the bones, the default) or false");
      c.pelvis = value.get<bool>();
    } else if (key == "geometry_stale_ms") c.geometry_stale_ms = number_field(path, value, key, 10, 600000, "ms");
    else if (key == "zoom_modes" || key == "zoom_mode") continue;  // below: they need the detector
    else bad_field(path, key, "unknown setting");
  }
  if (const auto it = j.find("zoom_modes"); it != j.end()) {
    if (!c.detector)
      bad_field(path, "zoom_modes", "needs \"detector\": the physical detector whose parts the modes show");
    c.zoom_modes = geometry::parse_zoom_modes(*it, *c.detector, path);
  }
  if (const auto it = j.find("zoom_mode"); it != j.end()) {
    if (c.zoom_modes.empty()) bad_field(path, "zoom_mode", "needs \"zoom_modes\", the modes to fix one of");
    if (!it->is_number_integer() || !geometry::find_zoom_mode(c.zoom_modes, it->get<int>()))
      bad_field(path, "zoom_mode", "must be the number of one of zoom_modes, found " + it->dump());
    c.zoom_mode = it->get<int>();
  }
  return c;
}

}  // namespace evar::app
