#pragma once
// The picture `evarnode deform` leaves beside its outputs.
#include <filesystem>

#include "evar/deform/scene_deformation.hpp"
#include "evar/geometry/scene.hpp"

namespace evar::app {

void write_preview(const std::filesystem::path& png, const geometry::Scene& scene,
                   const deform::SceneDeformation& result, const geometry::Polyline& device);

}  // namespace evar::app
