// `evarnode example`: writes the bundled synthetic scene.
#include "commands.hpp"
#include "evar/node/logging.hpp"
#include "evar/sim/example_scene.hpp"

#include <stdexcept>

namespace evar::app {

geometry::MeshFormat mesh_format_option(const std::string& name) {
  if (name == "ply") return geometry::MeshFormat::PlyBinary;
  if (name == "obj") return geometry::MeshFormat::Obj;
  if (name == "stl") return geometry::MeshFormat::StlBinary;
  if (name == "vtk") return geometry::MeshFormat::VtkBinary;
  if (name == "vtp") return geometry::MeshFormat::Vtp;
  throw std::invalid_argument("--format: '" + name + "' (expected stl, ply, obj, vtk or vtp)");
}

int run_example(const SyntheticSceneCommand& cmd) {
  sim::ExampleSceneParams params;
  params.seed = cmd.seed;
  params.aorta_vertices = cmd.aorta_vertices;
  params.iliac_vertices = cmd.iliac_vertices;
  const auto scene = sim::make_example_scene(params);
  const auto format = mesh_format_option(cmd.format);
  sim::write_example_scene(scene, cmd.out, format);
  for (const auto& c : scene.device_clearance)
    node::log().info("device vs {:<11}: up to {:.1f} mm outside the undeformed lumen over {:.0f} mm", c.vessel,
               c.max_outside_mm, c.length_outside_mm);
  node::log().info("wrote the example scene to {} (scene.json, device.mrk.json)", cmd.out.string());
  return 0;
}

}  // namespace evar::app
