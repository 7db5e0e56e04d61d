// A real segmentation's scene (VMTK's aorto-iliac test data, ../shared/data/vmtk-aorta,
// made into a scene by `evarnode scene`'s preparation): preparing its solver once (proxies
// included), then each later deformation. Skipped, saying so, where the data is absent.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>

#include "bulged_wire.hpp"
#include "proxy_files.hpp"
#include "evar/deform/scene_deformation.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/prepare/scene_preparation.hpp"

namespace {

namespace fs = std::filesystem;

std::optional<fs::path> vmtk_dir() {
  const char* env = std::getenv("EVAR_SHARED_DATA");
  const fs::path root = env && *env ? fs::path(env) : fs::path(EVAR_SOURCE_DIR) / ".." / "shared" / "data";
  if (!fs::exists(root / "vmtk-aorta" / "aorta-surface.vtp")) return std::nullopt;
  return root / "vmtk-aorta";
}

// The prepared scene (loaded as deform loads it), made once, and a wire bulged 8 mm out of
// the right iliac.
struct VmtkScene {
  evar::geometry::Scene scene;
  evar::geometry::Scene scene_with_proxy_files;  ///< as `evarnode scene` leaves it
  evar::geometry::Polyline wire;
};

const VmtkScene* vmtk_scene() {
  static const std::unique_ptr<VmtkScene> made = []() -> std::unique_ptr<VmtkScene> {
    const auto dir = vmtk_dir();
    if (!dir) return nullptr;
    const auto prepared = evar::prepare::prepare_scene(
        {*dir / "aorta-surface.vtp", *dir / "aorta-centerline.vtp", {}, "RSP"});
    const fs::path out = fs::temp_directory_path() / "evar_bench_vmtk_scene";
    fs::remove_all(out);
    auto s = std::make_unique<VmtkScene>();
    s->scene = evar::geometry::load_scene(evar::prepare::write_prepared_scene(prepared, out, 0.89));
    s->wire = evar::bench::bulged_wire(s->scene);
    s->scene_with_proxy_files = evar::bench::with_proxy_files(s->scene, out);
    return s;
  }();
  return made.get();
}

// Preparing the scene's solver: proxies, skeletons, factorizations (paid once per scene);
// the proxies made (BM_VmtkSceneSolver) or read from the files `evarnode scene` keeps beside
// the meshes (BM_VmtkSceneSolverFromProxyFiles).
void scene_solver(benchmark::State& state, bool from_proxy_files) {
  const VmtkScene* s = vmtk_scene();
  if (!s) {
    state.SkipWithError("../shared/data/vmtk-aorta is absent (set EVAR_SHARED_DATA)");
    return;
  }
  for (auto _ : state) {
    const evar::deform::SceneDeformer deformer(from_proxy_files ? s->scene_with_proxy_files : s->scene);
    benchmark::DoNotOptimize(deformer.precompute_ms());
  }
}
void BM_VmtkSceneSolver(benchmark::State& state) { scene_solver(state, false); }
void BM_VmtkSceneSolverFromProxyFiles(benchmark::State& state) { scene_solver(state, true); }
BENCHMARK(BM_VmtkSceneSolver)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_VmtkSceneSolverFromProxyFiles)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Each later deformation of the prepared scene by the wire (containment check included).
void BM_VmtkDeform(benchmark::State& state) {
  const VmtkScene* s = vmtk_scene();
  if (!s) {
    state.SkipWithError("../shared/data/vmtk-aorta is absent (set EVAR_SHARED_DATA)");
    return;
  }
  const evar::deform::SceneDeformer deformer(s->scene);
  for (auto _ : state) benchmark::DoNotOptimize(deformer.deform(s->wire).total_ms);
}
BENCHMARK(BM_VmtkDeform)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace
