// `evarnode deform`: the deformation stage on files.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <optional>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "evar/deform/pelvis_shift.hpp"
#include "evar/deform/scene_deformation.hpp"
#include "evar/base/input_error.hpp"
#include "evar/base/quantity_text.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/node/logging.hpp"
#include "json_file.hpp"
#include "preview.hpp"

namespace evar::app {
namespace {

nlohmann::json vec(const Eigen::Vector3d& p) { return {p.x(), p.y(), p.z()}; }

nlohmann::json vessel_json(const deform::VesselReport& r, const std::string& output) {
  return {{"name", r.name},
          {"kind", r.kind},
          {"role", r.role},
          {"output", output},
          {"vertices", r.vertices},
          {"faces", r.faces},
          {"proxy_vertices", r.proxy_vertices},
          {"proxy_edge_mm", r.proxy_vertices > 0 ? nlohmann::json(r.proxy_edge_mm) : nlohmann::json()},
          {"proxy_refused", r.proxy_refused},
          {"proxy_file", r.proxy_file},
          {"proxy_file_unused", r.proxy_file_unused},
          {"device_points", r.device_points},
          {"control_points", r.control_points},
          {"bound_vertices", r.bound_vertices},
          {"junction_gap_mm", r.bound_vertices > 0 ? nlohmann::json(r.junction_gap_mm) : nlohmann::json()},
          {"constrained_vertices", r.constrained_vertices},
          {"skeleton_points", r.skeleton_points},
          {"rounds", r.rounds},
          {"iterations", r.iterations},
          {"anderson_rejections", r.anderson_rejections},
          {"coarse_fallbacks", r.coarse_fallbacks},
          {"converged", r.converged},
          {"final_energy", r.final_energy},
          {"max_displacement_mm", r.max_displacement_mm},
          {"erased_vertices", r.erased_vertices},
          {"erased_faces", r.erased_faces},
          {"timings_ms",
           {{"weights", r.timings.weights_ms},
            {"control_points", r.timings.control_points_ms},
            {"skeleton", r.timings.skeleton_ms},
            {"factor", r.timings.factor_ms},
            {"iterate", r.timings.iterate_ms},
            {"total", r.timings.total_ms}}}};
}

nlohmann::json containment_json(const deform::DeviceContainment& c) {
  nlohmann::json stretches = nlohmann::json::array();
  for (const auto& s : c.stretches)
    stretches.push_back({{"from_mm", s.from_mm}, {"to_mm", s.to_mm}, {"max_depth_mm", s.max_depth_mm},
                         {"nearest_vessel", s.nearest_vessel}});
  return {{"device_length_mm", c.device_length_mm},
          {"outside_length_mm", c.outside_length_mm},
          {"outside_max_depth_mm", c.outside_max_depth_mm},
          {"unjudged_length_mm", c.unjudged_length_mm},
          {"tolerance_mm", deform::kOutsideToleranceMm},
          {"stretches", stretches}};
}

}  // namespace

int run_deform(const DeformCommand& cmd) {
  node::log().info("loading scene {}", cmd.scene.string());
  const geometry::Scene scene = geometry::load_scene(cmd.scene);
  const geometry::Markup curve = geometry::read_curve(cmd.device, 2);
  geometry::Polyline device;
  for (const auto& p : curve.points) device.push_back(p.position_lps);
  node::log().info("device {}: {} points; {} vessel(s), {} landmark(s), device thickness {} mm", cmd.device.string(),
             device.size(), scene.vessels.size(), scene.landmarks.size(), scene.device_thickness_mm);

  deform::DeformOptions options;
  options.use_skeleton = cmd.skeleton;
  options.arap.backend = deform::parse_cholesky_backend(cmd.solver);
  options.arap.tolerance_mm = cmd.tolerance_mm;
  options.arap.max_iterations = cmd.max_iterations;
  options.containment_rounds = cmd.containment_rounds;
  options.tether_length_mm = cmd.tether_mm;
  options.arap.coarse_rotations = cmd.coarse_rotations;
  options.control.pair_in_order = cmd.ordered_pairing;
  options.proxy_edge_mm = cmd.proxy_edge_mm;
  // The pelvis moved against the registered models: the models go with it before bending.
  std::optional<deform::PelvisShift> pelvis;
  geometry::Scene shifted;
  if (!cmd.pelvis_shift_mm.empty()) {
    try {
      pelvis = deform::pelvis_shift_for(
          scene, Eigen::Vector3d(cmd.pelvis_shift_mm[0], cmd.pelvis_shift_mm[1], cmd.pelvis_shift_mm[2]));
    } catch (const base::InputError& e) {
      throw base::InputError(std::string("--pelvis-shift-mm: ") + e.what());
    }
    shifted = scene;
    deform::apply(*pelvis, shifted);
    node::log().info("pelvis shifted by {} (LPS): the models moved with it from the aortic bifurcation down, "
                     "ramping from the renal level", fmt::format("({:.1f}, {:.1f}, {:.1f}) mm", pelvis->shift_mm.x(),
                                                                  pelvis->shift_mm.y(), pelvis->shift_mm.z()));
  }
  deform::SceneDeformation result;
  try {
    result = deform::deform_scene(pelvis ? shifted : scene, device, options);
  } catch (const base::InputError& e) {
    const std::string what = e.what();
    if (what.rfind("device:", 0) == 0) throw base::InputError(cmd.device.string() + ": " + what.substr(8));
    throw;
  }

  // Outputs must not overwrite an input or each other (vessel mesh files are named after
  // their input files; two inputs from different folders may share a name).
  std::vector<std::filesystem::path> inputs{cmd.scene, cmd.device, scene.landmarks_path};
  for (const auto& v : scene.vessels) inputs.insert(inputs.end(), {v.mesh_path, v.centerline_path});
  std::vector<std::filesystem::path> outputs{cmd.out / "landmarks.mrk.json", cmd.out / "report.json"};
  if (cmd.preview) outputs.push_back(cmd.out / "preview.png");
  for (const auto& v : scene.vessels) outputs.push_back(cmd.out / v.mesh_path.filename());
  const auto same_file = [](const std::filesystem::path& a, const std::filesystem::path& b) {
    std::error_code ec;
    return std::filesystem::weakly_canonical(a, ec) == std::filesystem::weakly_canonical(b, ec);
  };
  for (std::size_t i = 0; i < outputs.size(); ++i) {
    for (const auto& in : inputs)
      if (!in.empty() && same_file(outputs[i], in))
        throw base::InputError(outputs[i].string() + ": writing this output would overwrite an input; choose another --out");
    for (std::size_t j = 0; j < i; ++j)
      if (same_file(outputs[i], outputs[j]))
        throw base::InputError(outputs[i].string() + ": two outputs would have this name (vessel mesh files with the same name in different folders); rename one");
  }

  std::filesystem::create_directories(cmd.out);
  nlohmann::json report = {{"format", "evarnode-deform-report"},
                           {"version", 1},
                           {"scene", cmd.scene.string()},
                           {"device", cmd.device.string()},
                           {"device_iliac", result.device_iliac},
                           {"device_thickness_mm", scene.device_thickness_mm},
                           {"skeleton", cmd.skeleton},
                           {"solver", deform::to_string(options.arap.backend)},
                           {"tolerance_mm", cmd.tolerance_mm},
                           {"tether_mm", cmd.tether_mm},
                           {"coarse_rotations", cmd.coarse_rotations},
                           {"pairing", cmd.ordered_pairing ? "ordered" : "nearest"},
                           {"proxy_edge_mm", cmd.proxy_edge_mm},
                           {"pelvis_shift", pelvis ? nlohmann::json{{"shift_mm", vec(pelvis->shift_mm)},
                                                                    {"renal_point_mm", vec(pelvis->renal_point_mm)},
                                                                    {"bifurcation_point_mm", vec(pelvis->bifurcation_point_mm)}}
                                                   : nlohmann::json()},
                           {"vessels", nlohmann::json::array()},
                           {"landmarks", nlohmann::json::array()}};
  // The command that keeps this scene's proxies for later loads, at this call's edge.
  const std::string proxies_command =
      "evarnode proxies --scene " + cmd.scene.string() +
      (cmd.proxy_edge_mm == ProxiesCommand{}.proxy_edge_mm ? "" : " --proxy-edge-mm " + base::quantity_text(cmd.proxy_edge_mm, "", 3));
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    const auto& v = scene.vessels[i];
    const auto out_path = cmd.out / v.mesh_path.filename();
    geometry::write_mesh(out_path, result.vessels[i].mesh, v.mesh.format, v.mesh.space);
    const auto& r = result.reports[i];
    report["vessels"].push_back(vessel_json(r, out_path.string()));
    node::log().info("{:<12} {:<19} {:>3} control points, {:>4} constrained, {:>3} iterations in {} round(s), "
               "max displacement {:.2f} mm, {:.1f} ms{}",
               r.name, r.role, r.control_points, r.constrained_vertices, r.iterations, r.rounds,
               r.max_displacement_mm, r.timings.total_ms,
               r.erased_faces > 0 ? fmt::format(", {} faces erased", r.erased_faces) : "");
    if (r.proxy_vertices > 0)
      node::log().info("{:<12} solved on a proxy of {} vertices, edges of about {} (its {} follow it){}", r.name,
                       r.proxy_vertices, base::quantity_text(r.proxy_edge_mm, "mm", 2), r.vertices, r.proxy_file.empty() ? "" : ", read from " + std::filesystem::path(r.proxy_file).filename().string());
    if (!r.proxy_file_unused.empty())
      node::log().warn("{}: the scene's proxy file was not used, the proxy was made anew (seconds on a large mesh; "
                       "`{}` keeps a fresh one): {}",
                       r.name, proxies_command, r.proxy_file_unused);
    if (!r.proxy_refused.empty())
      node::log().warn("{}: solved on its own {} vertices, slower and less even than on a proxy: {}", r.name, r.vertices,
                 r.proxy_refused);
    if (!r.converged) node::log().warn("{}: ARAP stopped at the iteration cap before reaching {} mm", r.name, cmd.tolerance_mm);
  }
  const auto made_here = std::count_if(result.reports.begin(), result.reports.end(),
                                      [](const auto& r) { return r.proxy_vertices > 0 && r.proxy_file.empty(); });
  if (made_here > 0 && !pelvis)
    node::log().info("{} {} made at load in {:.0f} ms; `{}` keeps {} beside the meshes, so later "
                     "loads read {} in milliseconds",
                     made_here, made_here == 1 ? "proxy" : "proxies", result.proxy_ms, proxies_command,
                     made_here == 1 ? "it" : "them", made_here == 1 ? "it" : "them");
  geometry::Markup landmarks{"Fiducial", "landmarks", result.landmarks};
  geometry::write_markups(cmd.out / "landmarks.mrk.json", {landmarks});
  for (std::size_t k = 0; k < result.landmarks.size(); ++k) {
    const auto& before = scene.landmarks[k].position_lps;
    const auto& after = result.landmarks[k].position_lps;
    report["landmarks"].push_back({{"label", result.landmarks[k].label},
                                   {"vessel", result.landmark_vessel[k]},
                                   {"before_lps_mm", vec(before)},
                                   {"after_lps_mm", vec(after)},
                                   {"displacement_mm", (after - before).norm()}});
  }
  const auto& contained = result.containment;
  report["device_outside_length_mm"] = contained.outside_length_mm;
  report["device_outside_max_depth_mm"] = contained.outside_max_depth_mm;
  report["device_containment"] = containment_json(contained);
  report["timings_ms"] = {{"scene_solver", result.precompute_ms},
                          {"of_which_proxies", result.proxy_ms},
                          {"deform", result.total_ms - result.precompute_ms},
                          {"of_which_containment", result.containment_ms},
                          {"total", result.total_ms}};
  report["containment_ms"] = result.containment_ms;
  report["total_ms"] = result.total_ms;
  write_json(cmd.out / "report.json", report);
  if (cmd.preview) write_preview(cmd.out / "preview.png", scene, result, device);
  node::log().info("done in {:.1f} ms; wrote {} mesh(es), landmarks.mrk.json, report.json{} to {}", result.total_ms,
             scene.vessels.size(), cmd.preview ? ", preview.png" : "", cmd.out.string());
  if (deform::leaves_device_outside(contained)) {
    node::log().warn("{}: the adapted roadmap does not contain the device there; check the scene's centerlines and "
                     "meshes where it lies (docs/DEFORMATION.md, \"Device left outside\")",
                     deform::describe_outside(contained));
    if (cmd.strict) return kExitDeviceOutside;
  }
  return 0;
}

}  // namespace evar::app
