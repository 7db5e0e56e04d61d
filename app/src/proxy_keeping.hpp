#pragma once
// A scene's proxies kept beside its meshes and named in its scene.json (docs/FORMATS.md,
// "Proxy files"), so that deform, run and record read them instead of remeshing at every
// load: what `evarnode scene` does for the scenes it makes and `evarnode proxies` for any.
#include <filesystem>

#include "evar/deform/scene_deformation.hpp"
#include "evar/geometry/scene.hpp"

namespace evar::app {

/// Writes `<mesh stem>.proxy` beside scene.json for every vessel of `scene` (loaded from
/// `json`) whose proxy `deformer` made rather than read from the file scene.json names,
/// then adds `vessels[i].proxy` to scene.json (rewritten atomically, its other fields and
/// their order kept). A proxy that cannot be written is warned about and left out: the
/// scene stands without it. Returns how many vessels now name a usable proxy file.
int keep_proxies(const std::filesystem::path& json, const geometry::Scene& scene, const deform::SceneDeformer& deformer,
                 double edge_mm);

}  // namespace evar::app
