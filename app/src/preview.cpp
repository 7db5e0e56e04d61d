#include "preview.hpp"

#include <fmt/format.h>

#include "evar/overlay/mesh_preview.hpp"

namespace evar::app {

void write_preview(const std::filesystem::path& png, const geometry::Scene& scene,
                   const deform::SceneDeformation& result, const geometry::Polyline& device) {
  std::vector<geometry::TriangleMesh> before, after;
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    before.push_back(scene.vessels[i].mesh.mesh);
    after.push_back(result.vessels[i].mesh);
  }
  auto picture = overlay::deformation_comparison(fmt::format("evarnode deform: {}", scene.file.filename().string()),
                                                 std::move(before), std::move(after), device, scene.landmarks,
                                                 result.landmarks);
  double worst = 0.0;
  for (const auto& r : result.reports) worst = std::max(worst, r.max_displacement_mm);
  picture.subtitle = fmt::format("device in {}; largest vertex displacement {:.1f} mm; {:.0f} ms",
                                 result.device_iliac.empty() ? "the aorta only" : result.device_iliac, worst,
                                 result.total_ms);
  overlay::write_comparison_png(png, picture);
}

}  // namespace evar::app
