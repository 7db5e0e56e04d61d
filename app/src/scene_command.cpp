// `evarnode scene`: a segmentation's surface and centerlines made into a scene directory,
// checked by loading it as `deform` does, with a picture and a report.
#include <fmt/format.h>

#include <fstream>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "evar/deform/scene_deformation.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/node/logging.hpp"
#include "evar/overlay/mesh_preview.hpp"
#include "evar/prepare/scene_preparation.hpp"
#include "json_file.hpp"
#include "proxy_keeping.hpp"

namespace evar::app {
namespace {

nlohmann::json vec(const Eigen::Vector3d& p) { return {p.x(), p.y(), p.z()}; }

// The surface cut into its vessels, their centerlines, the ostia and an arrow to the head,
// in an AP and a lateral panel.
void write_scene_picture(const std::filesystem::path& png, const prepare::PreparedScene& scene, const std::string& title) {
  overlay::ComparisonPicture picture;
  picture.title = title;
  picture.subtitle = fmt::format("read as {}; AP (patient's right on the left) and lateral; head up", scene.axes);
  const overlay::Bgr colours[3] = {{60, 120, 230}, {80, 200, 120}, {230, 170, 60}};  // aorta, right, left
  const overlay::Bgr line{240, 240, 240};
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    const auto& v = scene.vessels[i];
    picture.overlay.layers.push_back({v.name, {v.mesh}, colours[i % 3], 0.35, true, 1});
    picture.overlay.polylines.push_back({i == 0 ? "centerlines" : "", v.centerline, line, 1});
  }
  for (const auto& lm : scene.landmarks) picture.overlay.markers.push_back({lm.position_lps, lm.label, "ostia", {40, 220, 250}, true, 5});
  // The arrow: from the inlet 25 mm toward the head, with its head as two short strokes.
  const Eigen::Vector3d tip = scene.inlet + Eigen::Vector3d(0, 0, 25);
  picture.overlay.polylines.push_back({"to the head", {scene.inlet, tip}, {90, 90, 255}, 2});
  picture.overlay.polylines.push_back({"", {tip + Eigen::Vector3d(-4, 0, -6), tip, tip + Eigen::Vector3d(4, 0, -6)}, {90, 90, 255}, 2});
  picture.overlay.polylines.push_back({"", {tip + Eigen::Vector3d(0, -4, -6), tip, tip + Eigen::Vector3d(0, 4, -6)}, {90, 90, 255}, 2});
  picture.overlay.markers.push_back({scene.bifurcation, "bifurcation", "", {250, 250, 250}, false, 4});
  overlay::write_comparison_png(png, picture);
}

}  // namespace

int run_scene(const SceneCommand& cmd) {
  node::log().info("preparing a scene from {}{}", cmd.surface.string(),
                   cmd.centerlines.empty()
                       ? " (no --centerlines: computing them from the surface's skeleton, seconds on a large surface)"
                       : " with centerlines " + cmd.centerlines.string());
  const prepare::PreparedScene scene =
      prepare::prepare_scene({cmd.surface, cmd.centerlines, cmd.ostia, cmd.axes});
  for (const auto& note : scene.notes) node::log().info("{}", note);
  const auto json = prepare::write_prepared_scene(scene, cmd.out, cmd.device_thickness_mm);

  // What deform and run will do with it: load it and make its solver (every scene check).
  const geometry::Scene loaded = geometry::load_scene(json);
  const deform::DeformOptions defaults;
  const deform::SceneDeformer deformer(loaded, defaults);
  const int proxies = keep_proxies(json, loaded, deformer, defaults.proxy_edge_mm).usable;
  nlohmann::json report = {{"format", "evarnode-scene-report"},
                           {"version", 1},
                           {"surface", cmd.surface.string()},
                           {"centerlines", cmd.centerlines.string()},
                           {"ostia", cmd.ostia.string()},
                           {"axes", scene.axes},
                           {"inlet_lps_mm", vec(scene.inlet)},
                           {"bifurcation_lps_mm", vec(scene.bifurcation)},
                           {"notes", scene.notes},
                           {"vessels", nlohmann::json::array()},
                           {"landmarks", scene.landmarks.size()},
                           {"prepare_ms", scene.prepare_ms},
                           {"solver_ms", deformer.precompute_ms()},
                           {"proxy_files", proxies}};
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    const auto& v = scene.vessels[i];
    report["vessels"].push_back({{"name", v.name},
                                 {"mesh", loaded.vessels[i].mesh_path.filename().string()},
                                 {"vertices", v.mesh.V.rows()},
                                 {"faces", v.mesh.F.rows()},
                                 {"closed", geometry::is_closed(v.mesh)},
                                 {"centerline_points", v.centerline.size()},
                                 {"centerline_length_mm", geometry::arc_lengths(v.centerline).back()},
                                 {"proxy_refused", deformer.proxy_refused(i)}});
    node::log().info("{:<12} {:>6} vertices, centerline {:.1f} mm", v.name, v.mesh.V.rows(),
                     geometry::arc_lengths(v.centerline).back());
  }
  write_json(cmd.out / "scene_report.json", report);
  if (cmd.picture) write_scene_picture(cmd.out / "scene.png", scene, "evarnode scene: " + cmd.surface.filename().string());
  node::log().info("wrote {} ({} vessels, {} landmarks){}{}; deform takes it (its solver made in {:.0f} ms{})", json.string(),
                   scene.vessels.size(), scene.landmarks.size(), cmd.picture ? ", scene.png" : "",
                   proxies > 0 ? fmt::format(", {} proxy file(s)", proxies) : "", deformer.precompute_ms(),
                   proxies > 0 ? fmt::format(", {:.0f} of them making the proxies, which deform now reads", deformer.proxy_ms()) : "");
  return 0;
}

}  // namespace evar::app
