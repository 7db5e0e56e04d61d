// scene.json ("evarnode-scene" version 1): the patient's vessels, landmarks and device.
#include "evar/geometry/scene.hpp"
#include "evar/base/atomic_file.hpp"
#include "evar/geometry/polyline.hpp"

#include <Eigen/Geometry>
#include <cctype>
#include <cmath>
#include <set>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

#include "evar/base/input_error.hpp"
#include "evar/geometry/json_fields.hpp"
#include "evar/base/quantity_text.hpp"
#include "mesh_formats.hpp"
#include "scene_checks.hpp"

namespace evar::geometry {

namespace {

using nlohmann::json;
namespace fs = std::filesystem;

constexpr const char* kFormat = "evarnode-scene";
constexpr int kVersion = 1;

[[noreturn]] void bad(const fs::path& file, const std::string& field, const std::string& what) {
  detail::fail(file, field + ": " + what);
}

using detail::parse_json_file;

using detail::member;

std::string string_field(const fs::path& file, const json& object, const char* key,
                         const std::string& field) {
  const json& j = member(file, object, key, field);
  if (!j.is_string()) bad(file, field, std::string("expected a string, found ") + j.type_name());
  std::string s = j.get<std::string>();
  if (s.empty()) bad(file, field, "is empty");
  return s;
}

void expect_value(const fs::path& file, const json& root, const char* key, const std::string& expected) {
  const std::string value = string_field(file, root, key, key);
  if (value != expected) {
    bad(file, key, "expected \"" + expected + "\", found \"" + value + "\"");
  }
}

VesselKind parse_kind(const fs::path& file, const std::string& kind, const std::string& field) {
  if (kind == "aorta") return VesselKind::Aorta;
  if (kind == "iliac") return VesselKind::Iliac;
  bad(file, field, "unknown vessel kind \"" + kind + "\" (expected \"aorta\" or \"iliac\")");
}

MeshSpace parse_space(const fs::path& file, const std::string& space, const std::string& field) {
  if (space == "LPS") return MeshSpace::Lps;
  if (space == "RAS") return MeshSpace::Ras;
  bad(file, field, "unknown coordinate system \"" + space + "\" (expected \"LPS\" or \"RAS\")");
}

const char* space_name(MeshSpace space) { return space == MeshSpace::Ras ? "RAS" : "LPS"; }

// A mesh file that says nothing is in the system the scene declares for it; one that says
// something must say the same (two sources that disagree cannot both be right).
void apply_declared_space(const fs::path& file, const std::string& field, const Vessel& vessel, LoadedMesh& loaded) {
  if (vessel.declared_mesh_space == MeshSpace::Undeclared) return;
  if (loaded.space == MeshSpace::Undeclared) {
    if (vessel.declared_mesh_space == MeshSpace::Ras) detail::flip_lps_ras(loaded.mesh);
    loaded.space = vessel.declared_mesh_space;
    return;
  }
  if (loaded.space != vessel.declared_mesh_space)
    bad(file, field, "is \"" + std::string(space_name(vessel.declared_mesh_space)) + "\", but " +
                         vessel.mesh_path.string() + " declares SPACE=" + space_name(loaded.space) +
                         " in its header; remove one of the two");
}

// A nested file's own error already names that file; prefix the scene field that named it.
template <class F>
auto loading(const fs::path& scene, const std::string& field, F&& load) {
  try {
    return load();
  } catch (const base::InputError& e) {
    bad(scene, field, e.what());
  }
}

}  // namespace

const char* to_string(VesselKind kind) {
  switch (kind) {
    case VesselKind::Aorta: return "aorta";
    case VesselKind::Iliac: return "iliac";
  }
  return "unknown";
}

Scene load_scene(const std::filesystem::path& scene_json) {
  const fs::path& file = scene_json;
  const json root = parse_json_file(file);
  if (!root.is_object()) {
    detail::fail(file, std::string("top level: expected a JSON object, found ") + root.type_name());
  }

  expect_value(file, root, "format", kFormat);
  const json& version = member(file, root, "version", "version");
  if (!version.is_number_integer() || version.get<long long>() != kVersion) {
    bad(file, "version", "unsupported version " + version.dump() + " (this build reads version 1)");
  }
  expect_value(file, root, "coordinate_system", "LPS");
  expect_value(file, root, "units", "mm");

  Scene scene;
  scene.file = file;
  const json& thickness = member(file, root, "device_thickness_mm", "device_thickness_mm");
  if (!thickness.is_number()) {
    bad(file, "device_thickness_mm", std::string("expected a number, found ") + thickness.type_name());
  }
  scene.device_thickness_mm = thickness.get<double>();
  // Guidewires are ~0.9 mm, the largest EVAR delivery sheaths 24 F = 8 mm.
  if (!std::isfinite(scene.device_thickness_mm) || scene.device_thickness_mm < 0.0 || scene.device_thickness_mm > 15.0) {
    bad(file, "device_thickness_mm", "must be a number from 0 to 15 (mm), found " + thickness.dump());
  }

  const json& vessels = member(file, root, "vessels", "vessels");
  if (!vessels.is_array()) bad(file, "vessels", std::string("expected an array, found ") + vessels.type_name());
  if (vessels.empty()) bad(file, "vessels", "the scene has no vessels");

  // Check every field before reading any mesh: cheap mistakes are reported first.
  const fs::path dir = file.parent_path();
  std::set<std::string> names;
  int aortas = 0;
  for (std::size_t i = 0; i < vessels.size(); ++i) {
    const std::string field = "vessels[" + std::to_string(i) + "]";
    const json& v = vessels[i];
    if (!v.is_object()) bad(file, field, std::string("expected an object, found ") + v.type_name());
    Vessel vessel{};  // value-initialized: LoadedMesh::format has no default
    vessel.name = string_field(file, v, "name", field + ".name");
    if (!names.insert(vessel.name).second) {
      bad(file, field + ".name", "another vessel is already named \"" + vessel.name + "\"");
    }
    vessel.kind = parse_kind(file, string_field(file, v, "kind", field + ".kind"), field + ".kind");
    if (vessel.kind == VesselKind::Aorta && ++aortas > 1) {
      bad(file, field + ".kind", "a second vessel of kind \"aorta\"; the scene needs exactly one");
    }
    // operator/ keeps an absolute path as it is.
    vessel.mesh_path = dir / string_field(file, v, "mesh", field + ".mesh");
    vessel.centerline_path = dir / string_field(file, v, "centerline", field + ".centerline");
    // Missing or null: nothing declared (as for "landmarks").
    if (v.contains("mesh_coordinate_system") && !v.at("mesh_coordinate_system").is_null())
      vessel.declared_mesh_space = parse_space(file, string_field(file, v, "mesh_coordinate_system", field + ".mesh_coordinate_system"),
                                               field + ".mesh_coordinate_system");
    if (v.contains("proxy") && !v.at("proxy").is_null()) vessel.proxy_path = dir / string_field(file, v, "proxy", field + ".proxy");
    scene.vessels.push_back(std::move(vessel));
  }
  if (aortas == 0) bad(file, "vessels", "no vessel of kind \"aorta\"; the scene needs exactly one");

  const auto landmarks = root.find("landmarks");
  if (landmarks != root.end() && !landmarks->is_null()) {
    scene.landmarks_path = dir / string_field(file, root, "landmarks", "landmarks");
  }

  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    Vessel& vessel = scene.vessels[i];
    const std::string field = "vessels[" + std::to_string(i) + "]";
    vessel.mesh = loading(file, field + ".mesh", [&] {
      LoadedMesh loaded = read_mesh(vessel.mesh_path);
      validate_mesh(loaded.mesh, vessel.mesh_path.string());
      return loaded;
    });
    apply_declared_space(file, field + ".mesh_coordinate_system", vessel, vessel.mesh);
    const Markup curve = loading(file, field + ".centerline", [&] {
      return read_curve(vessel.centerline_path, 2);
    });
    vessel.centerline.reserve(curve.points.size());
    for (const ControlPoint& p : curve.points) vessel.centerline.push_back(p.position_lps);
    // A centerline is walked along in steps of millimetres: it needs extent, and a length
    // no vessel has (10 m) means a stray control point.
    const double length = arc_lengths(vessel.centerline).back();
    if (!(length > 0.0) || length > 1e4)
      bad(file, field + ".centerline",
          vessel.centerline_path.string() + ": the curve's length is " + base::quantity_text(length, "mm") +
              "; a vessel centerline needs a length between 0 and 10000 mm (a stray control point?)");
  }

  detail::check_vessels_apart(scene);

  const auto pelvis = root.find("pelvis");
  if (pelvis != root.end() && !pelvis->is_null()) {
    scene.pelvis_path = dir / string_field(file, root, "pelvis", "pelvis");
    scene.pelvis = loading(file, "pelvis", [&] {
      LoadedMesh loaded = read_mesh(scene.pelvis_path);
      validate_mesh(loaded.mesh, scene.pelvis_path.string());
      return loaded.mesh;
    });
    if (!is_closed(scene.pelvis))
      bad(file, "pelvis", scene.pelvis_path.string() +
                              ": the bones' surface is not closed (an edge not shared by exactly two faces); the pelvis's "
                              "image is made of the bone's thickness along each ray, which needs closed surfaces: export "
                              "the bone segmentation as a closed surface (3D Slicer: Segmentations > Export to models)");
    // Outward faces: the bone's thickness along a ray is counted from which way it crosses them.
    const double volume_mm3 = enclosed_volume(scene.pelvis);
    if (!(volume_mm3 > 0.0))
      bad(file, "pelvis", scene.pelvis_path.string() +
                              ": the bones' faces point inward (the surface encloses a negative volume); reverse the "
                              "faces' order (3D Slicer: Surface Toolbox > Normals > Flip normals) and save it again");
  }

  if (!scene.landmarks_path.empty()) {
    scene.landmarks = loading(file, "landmarks", [&] { return read_fiducials(scene.landmarks_path); });
    if (scene.landmarks.empty()) {
      bad(file, "landmarks", scene.landmarks_path.string() + ": no \"Fiducial\" control points in the file");
    }
  }
  return scene;
}

void write_scene_manifest(const std::filesystem::path& scene_json, const SceneManifest& manifest) {
  // Refuse to write a scene that load_scene would reject.
  auto invalid = [&](const std::string& what) {
    throw std::invalid_argument(scene_json.string() + ": cannot write scene: " + what);
  };
  if (manifest.vessels.empty()) invalid("no vessels");
  if (!std::isfinite(manifest.device_thickness_mm) || manifest.device_thickness_mm < 0.0) {
    invalid("device_thickness_mm must be finite and >= 0");
  }
  std::set<std::string> names;
  int aortas = 0;
  using ordered = nlohmann::ordered_json;  // keep the documented field order
  ordered vessels = ordered::array();
  for (const auto& v : manifest.vessels) {
    if (v.name.empty() || v.mesh.empty() || v.centerline.empty()) {
      invalid("vessel \"" + v.name + "\" has an empty name, mesh or centerline");
    }
    if (!names.insert(v.name).second) invalid("two vessels named \"" + v.name + "\"");
    if (v.kind != "aorta" && v.kind != "iliac") invalid("vessel \"" + v.name + "\" has kind \"" + v.kind + "\"");
    if (v.kind == "aorta") ++aortas;
    if (!v.mesh_coordinate_system.empty() && v.mesh_coordinate_system != "LPS" && v.mesh_coordinate_system != "RAS")
      invalid("vessel \"" + v.name + "\" has mesh_coordinate_system \"" + v.mesh_coordinate_system + "\"");
    ordered entry = {{"name", v.name}, {"kind", v.kind}, {"mesh", v.mesh}, {"centerline", v.centerline}};
    if (!v.mesh_coordinate_system.empty()) entry["mesh_coordinate_system"] = v.mesh_coordinate_system;
    if (!v.proxy.empty()) entry["proxy"] = v.proxy;
    vessels.push_back(std::move(entry));
  }
  if (aortas != 1) invalid("exactly one vessel must be of kind \"aorta\"");

  ordered root = {{"format", kFormat},
                  {"version", kVersion},
                  {"coordinate_system", "LPS"},
                  {"units", "mm"},
                  {"vessels", std::move(vessels)}};
  if (!manifest.landmarks.empty()) root["landmarks"] = manifest.landmarks;
  if (!manifest.pelvis.empty()) root["pelvis"] = manifest.pelvis;
  root["device_thickness_mm"] = manifest.device_thickness_mm;
  base::write_file_atomically(scene_json, root.dump(2, ' ', false, ordered::error_handler_t::replace) + "\n");
}

std::filesystem::path copy_scene(const Scene& scene, const std::filesystem::path& directory) {
  namespace fs = std::filesystem;
  fs::create_directories(directory);
  // Vessel names are free text: keep letters, digits, '-' and '_' in the file names.
  auto file_stem = [](const std::string& name) {
    std::string s;
    for (char c : name) s += std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' ? c : '_';
    return s;
  };
  auto copy = [&](const fs::path& from, const std::string& to) {
    fs::copy_file(from, directory / to);  // throws rather than overwrite: every file is new
    return to;
  };
  auto markup_suffix = [](const fs::path& p) {
    const std::string n = p.filename().string();
    return n.size() > 9 && n.ends_with(".mrk.json") ? std::string(".mrk.json") : p.extension().string();
  };
  SceneManifest m;
  m.device_thickness_mm = scene.device_thickness_mm;
  std::set<std::string> used;
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    const Vessel& v = scene.vessels[i];
    std::string stem = file_stem(v.name);
    for (int k = 1; !used.insert(stem).second; ++k) {  // two names that clean alike
      stem = file_stem(v.name);
      stem += '_';
      stem += std::to_string(k);
    }
    // The files are copied as they are, so a system the scene declared for a mesh goes along.
    m.vessels.push_back({v.name, to_string(v.kind), copy(v.mesh_path, stem + v.mesh_path.extension().string()),
                         copy(v.centerline_path, std::string(stem).append(".centerline").append(markup_suffix(v.centerline_path))),
                         v.declared_mesh_space == MeshSpace::Undeclared ? std::string() : space_name(v.declared_mesh_space)});
    // The proxy goes along when there is one (it is only a cache: a missing one is made anew).
    if (!v.proxy_path.empty() && fs::exists(v.proxy_path)) m.vessels.back().proxy = copy(v.proxy_path, stem + ".proxy");
  }
  if (!scene.landmarks_path.empty()) m.landmarks = copy(scene.landmarks_path, std::string("landmarks").append(markup_suffix(scene.landmarks_path)));
  if (!scene.pelvis_path.empty()) m.pelvis = copy(scene.pelvis_path, "pelvis" + scene.pelvis_path.extension().string());
  const fs::path json = directory / "scene.json";
  write_scene_manifest(json, m);
  return json;
}

}  // namespace evar::geometry
