#pragma once
// A prepared scene as `evarnode scene` leaves it: each vessel's proxy kept in a file beside
// it and named by the scene, so the solver reads the proxies instead of remeshing.
#include <filesystem>

#include "evar/deform/mesh_proxy_file.hpp"
#include "evar/deform/scene_deformation.hpp"
#include "evar/geometry/scene.hpp"

namespace evar::bench {

inline geometry::Scene with_proxy_files(geometry::Scene scene, const std::filesystem::path& dir) {
  const deform::DeformOptions defaults;
  const deform::SceneDeformer deformer(scene, defaults);
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    if (!deformer.proxy(i)) continue;
    scene.vessels[i].proxy_path = dir / (scene.vessels[i].name + ".proxy");
    deform::write_mesh_proxy(scene.vessels[i].proxy_path, *deformer.proxy(i), scene.vessels[i].mesh.mesh,
                             defaults.proxy_edge_mm);
  }
  return scene;
}

}  // namespace evar::bench
