#include <fmt/format.h>

#include "commands.hpp"
#include "evar/base/quantity_text.hpp"
#include "evar/deform/mesh_proxy.hpp"
#include "evar/deform/scene_deformation.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/geometry/triangle_mesh.hpp"
#include "evar/node/logging.hpp"
#include "proxy_keeping.hpp"

namespace evar::app {

int run_proxies(const ProxiesCommand& cmd) {
  const geometry::Scene scene = geometry::load_scene(cmd.scene);
  deform::DeformOptions options;
  options.proxy_edge_mm = cmd.proxy_edge_mm;
  node::log().info("making the proxies of {} at edges of about {} (a second or more per large mesh)", cmd.scene.string(),
                   base::quantity_text(cmd.proxy_edge_mm, "mm", 2));
  const deform::SceneDeformer deformer(scene, options);
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    const auto& v = scene.vessels[i];
    const auto& mesh = v.mesh.mesh;
    const deform::MeshProxy* proxy = deformer.proxy(i);
    const auto& origin = deformer.proxy_origin(i);
    if (!origin.unused.empty()) node::log().info("{}: its proxy file is not usable ({}); made anew", v.name, origin.unused);
    if (proxy && !origin.file.empty())
      node::log().info("{:<12} proxy file {} is current: kept as it is", v.name, origin.file);
    else if (proxy)
      node::log().info("{:<12} proxy of {} vertices, edges of about {}, for its {} vertices", v.name, proxy->coarse.V.rows(),
                       base::quantity_text(proxy->edge_mm, "mm", 2), mesh.V.rows());
    else if (deformer.proxy_refused(i).empty())  // a refusal: keep_proxies says it
      node::log().info("{:<12} {} vertices, median edge {}: solved as it is, no proxy needed", v.name, mesh.V.rows(),
                       base::quantity_text(geometry::median_edge_length(mesh), "mm", 2));
  }
  const KeptProxies kept = keep_proxies(cmd.scene, scene, deformer, cmd.proxy_edge_mm);
  node::log().info("{} names {} proxy file(s); deform, run and record read them when given the same --proxy-edge-mm "
                   "(reading or making them took {:.0f} ms here)",
                   cmd.scene.filename().string(), kept.usable, deformer.proxy_ms());
  if (kept.failed > 0) {
    node::log().error("{} proxy file(s) could not be written beside {} (see above): is its folder writable?", kept.failed,
                      cmd.scene.string());
    return 1;
  }
  return 0;
}

}  // namespace evar::app
