#pragma once
// A scene's proxies kept beside its meshes and named in its scene.json (docs/FORMATS.md,
// "Proxy files"), so that deform, run and record read them instead of remeshing at every
// load: what `evarnode scene` does for the scenes it makes and `evarnode proxies` for any.
#include <filesystem>

#include "evar/deform/scene_deformation.hpp"
#include "evar/geometry/scene.hpp"

namespace evar::app {

struct KeptProxies {
  int usable = 0;  ///< vessels whose scene.json entry now names a current proxy file
  int failed = 0;  ///< proxies made that could not be written (warned about)
};

/// Writes `<vessel>.proxy` beside scene.json for every vessel of `scene` (loaded from
/// `json`) whose proxy `deformer` made rather than read from the file scene.json names,
/// and names it in `vessels[i].proxy`; removes the entry of a vessel that has no proxy now
/// (none needed, or refused at every edge). scene.json is rewritten atomically, its other
/// fields and their order kept, and only when something changed. A vessel refused a proxy
/// at every edge, and a proxy that cannot be written, are warned about and left out: the
/// scene stands without them.
KeptProxies keep_proxies(const std::filesystem::path& json, const geometry::Scene& scene,
                         const deform::SceneDeformer& deformer, double edge_mm);

}  // namespace evar::app
