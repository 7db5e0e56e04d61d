#include "proxy_keeping.hpp"

#include <fstream>
#include <nlohmann/json.hpp>

#include "evar/deform/mesh_proxy_file.hpp"
#include "evar/node/logging.hpp"
#include "json_file.hpp"

namespace evar::app {

KeptProxies keep_proxies(const std::filesystem::path& json, const geometry::Scene& scene,
                         const deform::SceneDeformer& deformer, double edge_mm) {
  std::ifstream in(json);
  auto manifest = nlohmann::ordered_json::parse(in);
  KeptProxies kept;
  bool changed = false;
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    auto& entry = manifest["vessels"][i];
    const deform::MeshProxy* proxy = deformer.proxy(i);
    if (!proxy) {
      if (!deformer.proxy_refused(i).empty())
        node::log().warn("{}: no proxy could be made, so deform solves its own {} vertices (slower, less even): {}",
                         scene.vessels[i].name, scene.vessels[i].mesh.mesh.V.rows(), deformer.proxy_refused(i));
      // No proxy (none needed, or every edge refused): a file the scene still names is stale.
      if (entry.contains("proxy")) entry.erase("proxy"), changed = true;
      continue;
    }
    if (!deformer.proxy_origin(i).file.empty()) {  // read from the file scene.json names: nothing to write
      ++kept.usable;
      continue;
    }
    // Named for the vessel (unique in a scene), not its mesh: two meshes of one name in
    // different folders would share a file.
    const std::string name = scene.vessels[i].name + ".proxy";
    try {
      deform::write_mesh_proxy(json.parent_path() / name, *proxy, scene.vessels[i].mesh.mesh, edge_mm);
    } catch (const std::exception& e) {  // the scene stands without it: deform makes the proxy itself
      node::log().warn("{}: its proxy could not be kept ({}); deform will make it at every load", scene.vessels[i].name,
                       e.what());
      if (entry.contains("proxy")) entry.erase("proxy"), changed = true;
      ++kept.failed;
      continue;
    }
    entry["proxy"] = name;
    changed = true;
    ++kept.usable;
  }
  if (changed) write_text(json, manifest.dump(2) + '\n');
  return kept;
}

}  // namespace evar::app
