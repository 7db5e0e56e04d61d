// 3D Slicer markups JSON (.mrk.json), read into LPS millimetres and written as LPS.
#include "evar/geometry/markups.hpp"
#include "evar/base/atomic_file.hpp"
#include "evar/geometry/triangle_mesh.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

#include "evar/base/input_error.hpp"
#include "evar/geometry/json_fields.hpp"
#include "mesh_formats.hpp"

namespace evar::geometry {

namespace {

using nlohmann::json;
namespace fs = std::filesystem;

constexpr const char* kSchema =
    "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/Resources/"
    "Schema/markups-schema-v1.0.3.json#";

// Every message is "<file>: <JSON path>: <what>" so the user can find the field.
[[noreturn]] void bad(const fs::path& file, const std::string& field, const std::string& what) {
  detail::fail(file, field + ": " + what);
}

using detail::parse_json_file;

std::string get_string(const fs::path& file, const json& j, const std::string& field) {
  if (!j.is_string()) bad(file, field, std::string("expected a string, found ") + j.type_name());
  return j.get<std::string>();
}

const json* find(const json& object, const char* key) {
  const auto it = object.find(key);
  return it == object.end() ? nullptr : &*it;
}

Eigen::Vector3d get_position(const fs::path& file, const json& j, const std::string& field) {
  if (!j.is_array() || j.size() != 3) {
    bad(file, field, "expected an array of 3 numbers, found " +
                         (j.is_array() ? "an array of " + std::to_string(j.size()) + " items"
                                       : std::string(j.type_name())));
  }
  Eigen::Vector3d p;
  for (int k = 0; k < 3; ++k) {
    const json& c = j[static_cast<std::size_t>(k)];
    if (!c.is_number()) {
      bad(file, field + "[" + std::to_string(k) + "]",
          std::string("expected a number, found ") + c.type_name());
    }
    p[k] = c.get<double>();
    if (!std::isfinite(p[k])) bad(file, field + "[" + std::to_string(k) + "]", "not finite");
    if (std::abs(p[k]) > kMaxCoordinateMm)
      bad(file, field + "[" + std::to_string(k) + "]", "implausibly far from the origin (coordinates are mm, within 100 m)");
  }
  return p;
}

// The markup's own "coordinateSystem" wins; a top-level one (not in the Slicer schema, but
// seen in hand-made files) is the fallback; LPS is the schema's default.
bool is_ras(const fs::path& file, const json& markup, const json& root, const std::string& field) {
  const json* cs = find(markup, "coordinateSystem");
  std::string cs_field = field + ".coordinateSystem";
  if (!cs) {
    cs = find(root, "coordinateSystem");
    cs_field = "coordinateSystem";
  }
  if (!cs) return false;
  const std::string name = get_string(file, *cs, cs_field);
  if (name == "LPS") return false;
  if (name == "RAS") return true;
  bad(file, cs_field, "unknown coordinate system '" + name + "' (expected \"LPS\" or \"RAS\")");
}

void check_units(const fs::path& file, const json& markup, const std::string& field) {
  const json* units = find(markup, "coordinateUnits");
  if (!units) return;
  const std::string units_field = field + ".coordinateUnits";
  // The schema allows "mm" or a DICOM-style code triple ["mm", "UCUM", "millimeter"].
  const json& code = units->is_array() && !units->empty() ? units->front() : *units;
  const std::string name = get_string(file, code, units_field);
  if (name != "mm") {
    bad(file, units_field, "unsupported unit '" + name + "' (only \"mm\" is supported)");
  }
}

Markup parse_markup(const fs::path& file, const json& root, const json& j, const std::string& field) {
  if (!j.is_object()) bad(file, field, std::string("expected an object, found ") + j.type_name());
  Markup m;
  const json* type = find(j, "type");
  if (!type) bad(file, field + ".type", "missing");
  m.type = get_string(file, *type, field + ".type");
  // null is read as "" for the free-text fields: some scripts write null there.
  if (const json* name = find(j, "name"); name && !name->is_null()) {
    m.name = get_string(file, *name, field + ".name");
  }
  const bool ras = is_ras(file, j, root, field);
  check_units(file, j, field);

  const json* points = find(j, "controlPoints");
  if (!points) return m;  // the schema's default is an empty list
  const std::string points_field = field + ".controlPoints";
  if (!points->is_array()) {
    bad(file, points_field, std::string("expected an array, found ") + points->type_name());
  }
  for (std::size_t i = 0; i < points->size(); ++i) {
    const json& cp = (*points)[i];
    const std::string cp_field = points_field + "[" + std::to_string(i) + "]";
    if (!cp.is_object()) bad(file, cp_field, std::string("expected an object, found ") + cp.type_name());
    // Only a placed point is a point. Slicer 5 also writes points not placed yet
    // ("undefined"), being placed ("preview"), or skipped ("missing", written at the
    // origin): used as points, a missing landmark sat at (0, 0, 0) and a missing device
    // point dragged the aorta 20 mm.
    if (const json* status = find(cp, "positionStatus")) {
      const std::string s = get_string(file, *status, cp_field + ".positionStatus");
      if (s == "undefined" || s == "preview" || s == "missing") continue;
      if (s != "defined")
        bad(file, cp_field + ".positionStatus",
            "\"" + s.substr(0, 40) + "\" (expected defined, undefined, preview or missing)");
    }
    ControlPoint point;
    if (const json* label = find(cp, "label"); label && !label->is_null()) {
      point.label = get_string(file, *label, cp_field + ".label");
    }
    const json* position = find(cp, "position");
    if (!position) bad(file, cp_field + ".position", "missing");
    point.position_lps = get_position(file, *position, cp_field + ".position");
    if (ras) {
      point.position_lps.x() = -point.position_lps.x();
      point.position_lps.y() = -point.position_lps.y();
    }
    m.points.push_back(std::move(point));
  }
  return m;
}

}  // namespace

std::vector<Markup> read_markups(const std::filesystem::path& path) {
  const json root = parse_json_file(path);
  if (!root.is_object()) {
    detail::fail(path, std::string("top level: expected a JSON object, found ") + root.type_name());
  }
  const json* markups = find(root, "markups");
  if (!markups) bad(path, "markups", "missing (is this a Slicer markups .mrk.json file?)");
  if (!markups->is_array()) {
    bad(path, "markups", std::string("expected an array, found ") + markups->type_name());
  }
  std::vector<Markup> result;
  result.reserve(markups->size());
  for (std::size_t i = 0; i < markups->size(); ++i) {
    result.push_back(parse_markup(path, root, (*markups)[i], "markups[" + std::to_string(i) + "]"));
  }
  return result;
}

Markup read_curve(const std::filesystem::path& path, std::size_t min_points) {
  std::vector<Markup> markups = read_markups(path);
  std::string found;
  std::vector<std::size_t> curves;
  for (std::size_t i = 0; i < markups.size(); ++i) {
    if (markups[i].type == "Curve" || markups[i].type == "ClosedCurve")
      curves.push_back(i);
    else
      found += (found.empty() ? "" : ", ") + markups[i].type;
  }
  if (curves.empty())
    detail::fail(path, "no markup of type \"Curve\" in the file" +
                           (found.empty() ? std::string(" (it has no markups)") : " (found: " + found + ")"));
  // One curve is asked for: taking the first of several would give every vessel the same.
  if (curves.size() > 1) {
    std::string names;
    for (std::size_t k = 0; k < curves.size() && k < 6; ++k)
      names += (k ? ", '" : "'") + markups[curves[k]].name + "'";
    if (curves.size() > 6) names += ", ...";
    detail::fail(path, "holds " + std::to_string(curves.size()) + " curves (" + names +
                           ") where one is expected: save each in a file of its own (3D Slicer: one markups node per "
                           "file), or give a whole centerline tree to `evarnode scene --centerlines`");
  }
  Markup& m = markups[curves.front()];
  if (m.points.size() < min_points)
    bad(path, "markups[" + std::to_string(curves.front()) + "].controlPoints",
        m.type + " '" + m.name + "' has " + std::to_string(m.points.size()) + " control points; at least " +
            std::to_string(min_points) + " are needed");
  return std::move(m);
}

std::vector<ControlPoint> read_fiducials(const std::filesystem::path& path) {
  std::vector<ControlPoint> points;
  for (Markup& m : read_markups(path)) {
    if (m.type != "Fiducial") continue;
    for (ControlPoint& p : m.points) points.push_back(std::move(p));
  }
  return points;
}

void write_markups(const std::filesystem::path& path, const std::vector<Markup>& markups) {
  using ordered = nlohmann::ordered_json;  // keeps Slicer's field order for human readers
  ordered list = ordered::array();
  for (const Markup& m : markups) {
    ordered points = ordered::array();
    for (std::size_t i = 0; i < m.points.size(); ++i) {
      const ControlPoint& p = m.points[i];
      if (!p.position_lps.allFinite()) {
        // JSON has no NaN; nlohmann would write null and the file would not read back.
        throw std::invalid_argument(path.string() + ": cannot write markup '" + m.name +
                                    "': control point " + std::to_string(i) + " is not finite");
      }
      points.push_back({
          {"id", std::to_string(i + 1)},
          {"label", p.label},
          {"description", ""},
          {"associatedNodeID", ""},
          {"position", {p.position_lps.x(), p.position_lps.y(), p.position_lps.z()}},
          {"orientation", {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0}},
          {"selected", true},
          {"locked", false},
          {"visibility", true},
          {"positionStatus", "defined"},
      });
    }
    list.push_back({
        {"type", m.type},
        {"name", m.name},
        {"coordinateSystem", "LPS"},
        {"coordinateUnits", "mm"},
        {"locked", false},
        {"fixedNumberOfControlPoints", false},
        {"labelFormat", "%N-%d"},
        {"lastUsedControlPointNumber", m.points.size()},
        {"controlPoints", std::move(points)},
    });
  }
  const ordered root = {{"@schema", kSchema}, {"markups", std::move(list)}};
  // Invalid UTF-8 in a label must not abort the write; it is replaced with U+FFFD.
  base::write_file_atomically(path, root.dump(4, ' ', false, ordered::error_handler_t::replace) + "\n");
}

}  // namespace evar::geometry
