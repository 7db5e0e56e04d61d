// A segmentation-like scene of the size issue 30 asks for (about 30k vertices, 0.7 mm
// edges): the simulator's segmentation phantom (marching cubes of a label volume) made into
// a scene by `evarnode scene`'s preparation, centerlines computed from the surface. Its
// centerlines from the surface, its solver (paid once per scene), then each deformation.
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <memory>

#include "bulged_wire.hpp"
#include "proxy_files.hpp"
#include "evar/deform/scene_deformation.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/ray_caster.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/prepare/scene_preparation.hpp"
#include "evar/prepare/surface_centerlines.hpp"
#include "evar/sim/segmentation_phantom.hpp"

namespace {

namespace fs = std::filesystem;

// Voxels of 0.55 x 0.55 x 0.8 mm, cropped from 15 mm below the bifurcation's crotch to 30 mm
// above the renal arteries: a surface of about 30k vertices, median edge about 0.7 mm.
const evar::sim::SegmentationPhantomOptions kOptions{
    .spacing_mm = {0.55, 0.55, 0.8}, .lowest_z_mm = -15.0, .highest_z_mm = 125.0};

struct PhantomScene {
  evar::sim::SegmentationPhantom phantom;
  evar::geometry::Scene scene;
  evar::geometry::Scene scene_with_proxy_files;  ///< as `evarnode scene` leaves it
  evar::geometry::Polyline wire;
};

const PhantomScene& phantom_scene() {
  static const std::unique_ptr<PhantomScene> made = [] {
    auto s = std::make_unique<PhantomScene>();
    s->phantom = evar::sim::make_segmentation_phantom(kOptions);
    const fs::path out = fs::temp_directory_path() / "evar_bench_phantom_scene";
    fs::remove_all(out);
    fs::create_directories(out);
    evar::geometry::write_mesh(out / "surface.ply", s->phantom.surface, evar::geometry::MeshFormat::PlyBinary,
                               evar::geometry::MeshSpace::Lps);
    const auto prepared = evar::prepare::prepare_scene({out / "surface.ply", {}, {}, ""});
    s->scene = evar::geometry::load_scene(evar::prepare::write_prepared_scene(prepared, out / "scene", 0.89));
    s->wire = evar::bench::bulged_wire(s->scene);
    s->scene_with_proxy_files = evar::bench::with_proxy_files(s->scene, out / "scene");
    return s;
  }();
  return *made;
}

// Centerlines from the surface alone (the mean-curvature-flow skeleton and what follows it),
// as `evarnode scene` computes them without --centerlines.
void BM_PhantomSurfaceCenterlines(benchmark::State& state) {
  const auto& s = phantom_scene();
  const evar::geometry::RayCaster walls(s.phantom.surface, evar::geometry::RayCaster::BuildQuality::Low);
  for (auto _ : state)
    benchmark::DoNotOptimize(evar::prepare::centerlines_from_surface(s.phantom.surface, walls, "phantom").paths.size());
  state.counters["vertices"] = static_cast<double>(s.phantom.surface.V.rows());
  state.counters["median_edge_mm"] = evar::geometry::median_edge_length(s.phantom.surface);
}
BENCHMARK(BM_PhantomSurfaceCenterlines)->Unit(benchmark::kMillisecond)->Iterations(3);

// Preparing the scene's solver: proxies, skeletons, factorizations (paid once per scene).
void BM_PhantomSceneSolver(benchmark::State& state) {
  const auto& s = phantom_scene();
  for (auto _ : state) {
    const evar::deform::SceneDeformer deformer(s.scene);
    benchmark::DoNotOptimize(deformer.precompute_ms());
  }
  Eigen::Index vertices = 0;
  for (const auto& v : s.scene.vessels) vertices += v.mesh.mesh.V.rows();
  state.counters["vertices"] = static_cast<double>(vertices);
  // Vessels solved on their own fine mesh because their proxy was refused (slower).
  const evar::deform::SceneDeformer deformer(s.scene);
  int refused = 0;
  for (std::size_t i = 0; i < s.scene.vessels.size(); ++i) refused += !deformer.proxy_refused(i).empty();
  state.counters["proxies_refused"] = refused;
}
BENCHMARK(BM_PhantomSceneSolver)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// The same with the proxies read from the files `evarnode scene` keeps beside the meshes.
void BM_PhantomSceneSolverFromProxyFiles(benchmark::State& state) {
  const auto& s = phantom_scene();
  for (auto _ : state) {
    const evar::deform::SceneDeformer deformer(s.scene_with_proxy_files);
    benchmark::DoNotOptimize(deformer.precompute_ms());
  }
}
BENCHMARK(BM_PhantomSceneSolverFromProxyFiles)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Each later deformation of the prepared scene by the wire (containment check included).
void BM_PhantomDeform(benchmark::State& state) {
  const auto& s = phantom_scene();
  const evar::deform::SceneDeformer deformer(s.scene);
  for (auto _ : state) benchmark::DoNotOptimize(deformer.deform(s.wire).total_ms);
}
BENCHMARK(BM_PhantomDeform)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace
