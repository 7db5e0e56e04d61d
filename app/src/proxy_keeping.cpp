#include "proxy_keeping.hpp"

#include <fstream>
#include <nlohmann/json.hpp>

#include "evar/deform/mesh_proxy_file.hpp"
#include "evar/node/logging.hpp"
#include "json_file.hpp"

namespace evar::app {

int keep_proxies(const std::filesystem::path& json, const geometry::Scene& scene, const deform::SceneDeformer& deformer,
                 double edge_mm) {
  std::ifstream in(json);
  auto manifest = nlohmann::ordered_json::parse(in);
  int usable = 0, written = 0;
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    const deform::MeshProxy* proxy = deformer.proxy(i);
    if (!proxy) continue;
    if (!deformer.proxy_origin(i).file.empty()) {  // read from the file scene.json names: nothing to write
      ++usable;
      continue;
    }
    const std::string name = scene.vessels[i].mesh_path.stem().string() + ".proxy";
    try {
      deform::write_mesh_proxy(json.parent_path() / name, *proxy, scene.vessels[i].mesh.mesh, edge_mm);
    } catch (const std::exception& e) {  // the scene stands without it: deform makes the proxy itself
      node::log().warn("{}: its proxy could not be kept ({}); deform will make it at every load", scene.vessels[i].name,
                       e.what());
      continue;
    }
    manifest["vessels"][i]["proxy"] = name;
    ++usable;
    ++written;
  }
  if (written > 0) write_text(json, manifest.dump(2) + '\n');
  return usable;
}

}  // namespace evar::app
