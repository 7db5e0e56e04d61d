#include "node_config.hpp"

#include <fstream>

#include <nlohmann/json.hpp>

#include "evar/geometry/input_error.hpp"

namespace evar::app {

namespace {

[[noreturn]] void fail(const std::filesystem::path& file, const std::string& field, const std::string& problem) {
  throw geometry::InputError(file.string() + ": " + field + ": " + problem);
}

double number(const nlohmann::json& j, const std::filesystem::path& file, const std::string& field, double lo, double hi) {
  if (!j.is_number()) fail(file, field, "expected a number");
  const double v = j.get<double>();
  if (!(v >= lo && v <= hi)) fail(file, field, std::to_string(v) + " is outside " + std::to_string(lo) + " to " + std::to_string(hi));
  return v;
}

std::string text(const nlohmann::json& j, const std::filesystem::path& file, const std::string& field) {
  if (!j.is_string()) fail(file, field, "expected a string");
  return j.get<std::string>();
}

}  // namespace

NodeConfig read_node_config(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) fail(path, "(file)", "cannot be read");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {  // syntax, and numbers beyond double (out_of_range)
    fail(path, "(file)", std::string("not JSON: ") + e.what());
  }
  if (!j.is_object()) fail(path, "(file)", "expected a JSON object");
  if (!j.contains("format") || j["format"] != "evarnode-node") fail(path, "format", "expected \"evarnode-node\"");
  if (!j.contains("version") || j["version"] != 1) fail(path, "version", "expected 1");
  NodeConfig c;
  c.file = path;
  const auto dir = path.parent_path();
  for (const auto& [key, value] : j.items()) {
    if (key == "format" || key == "version") continue;
    if (key == "scene") c.scene = dir / text(value, path, key);
    else if (key == "registration") c.registration = dir / text(value, path, key);
    else if (key == "detector") {
      if (!value.is_object()) fail(path, key, "expected an object");
      sim::DetectorSpec d;
      for (const char* f : {"cols", "rows", "row_spacing_mm", "col_spacing_mm"})
        if (!value.contains(f)) fail(path, key + "." + f, "missing");
      d.cols = static_cast<int>(number(value["cols"], path, "detector.cols", 1, 16384));
      d.rows = static_cast<int>(number(value["rows"], path, "detector.rows", 1, 16384));
      d.row_spacing_mm = number(value["row_spacing_mm"], path, "detector.row_spacing_mm", 1e-3, 10);
      d.col_spacing_mm = number(value["col_spacing_mm"], path, "detector.col_spacing_mm", 1e-3, 10);
      c.detector = d;
    } else if (key == "frames") {
      if (!value.is_object()) fail(path, key, "expected an object");
      FrameSourceSpec s;
      for (const auto& [k, v] : value.items()) {
        const std::string field = "frames." + k;
        if (k == "camera") s.camera = text(v, path, field);
        else if (k == "pixel_format") {
          s.pixel_format = text(v, path, field);
          if (s.pixel_format != "mono8" && s.pixel_format != "mono12" && s.pixel_format != "mono16")
            fail(path, field, "expected mono8, mono12 or mono16");
        } else if (k == "v4l2") s.v4l2 = text(v, path, field);
        else if (k == "v4l2_format") s.v4l2_format = text(v, path, field);
        else if (k == "width") s.width = static_cast<int>(number(v, path, field, 16, 16384));
        else if (k == "height") s.height = static_cast<int>(number(v, path, field, 16, 16384));
        else fail(path, field, "unknown setting");
      }
      c.frames = s;
    } else if (key == "carm") c.carm = text(value, path, key);
    else if (key == "fps") c.fps = number(value, path, key, 0.1, 1000);
    else if (key == "device_diameter_mm") c.device_diameter_mm = number(value, path, key, 0.1, 10);
    else if (key == "min_contrast") c.min_contrast = number(value, path, key, 0, 5);
    else if (key == "min_separation_deg") c.min_separation_deg = number(value, path, key, 5, 80);
    else if (key == "geometry_stale_ms") c.geometry_stale_ms = number(value, path, key, 10, 600000);
    else fail(path, key, "unknown setting");
  }
  return c;
}

}  // namespace evar::app
