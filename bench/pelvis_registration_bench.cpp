// The pelvis found in fluoroscopy (geometry/pelvis_registration.hpp): its bones' thickness
// image for one view, and the whole registration from two views 35° apart (512 x 512
// frames of the simulator's phantom, the pelvis 9 mm higher and 3° turned against the
// registration), and the check of one view's picture orientation by its bones
// (node/picture_orientation.hpp: the match as taken and under the 7 other turns). One
// core; docs/BENCHMARKS.md.
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <numbers>

#include "evar/geometry/pelvis_registration.hpp"
#include "evar/node/picture_orientation.hpp"
#include "evar/sim/body_phantom.hpp"
#include "evar/sim/xray_render.hpp"

namespace {

using namespace evar;

geometry::CArmView view(double primary_deg) {
  return {.primary_angle_deg = primary_deg, .source_to_detector_mm = 1200.0, .source_to_isocenter_mm = 800.0,
          .detector_cols = 512, .detector_rows = 512, .row_spacing_mm = 0.6, .col_spacing_mm = 0.6,
          .projection_matrix = std::nullopt};
}

struct Problem {
  geometry::TriangleMesh bones;
  std::vector<geometry::PelvisView> views;
};

const Problem& problem() {
  static const Problem p = [] {
    Problem out;
    const sim::BodyPhantom ct = sim::default_body_phantom(3);
    out.bones = sim::pelvis_mesh(ct);
    Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
    T.topRightCorner<3, 1>() = -Eigen::Vector3d(0.0, 20.0, -40.0);
    Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
    M.topLeftCorner<3, 3>() = Eigen::AngleAxisd(3.0 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitX()).toRotationMatrix();
    M.topRightCorner<3, 1>() = Eigen::Vector3d(0.0, 0.0, 9.0);
    for (const double primary : {0.0, 35.0}) {
      sim::XRayContent content;
      content.body = &ct;
      content.patient_to_world = T * M;
      out.views.push_back({geometry::registered(geometry::projection_matrix(view(primary)), T),
                           sim::detect(sim::expected_xray(view(primary), content).quanta, {}, 5), ""});
    }
    return out;
  }();
  return p;
}

void BM_BoneThicknessImage(benchmark::State& state) {
  const Problem& p = problem();
  const geometry::RayCaster caster(p.bones);
  for (auto _ : state)
    benchmark::DoNotOptimize(geometry::bone_thickness_image(caster, p.views[0].P_ct, 512, 512, static_cast<int>(state.range(0))));
}
BENCHMARK(BM_BoneThicknessImage)->Arg(4)->ArgName("step")->Unit(benchmark::kMillisecond);

void BM_PelvisRegistration(benchmark::State& state) {
  const Problem& p = problem();
  geometry::PelvisRegistration r;
  for (auto _ : state) {
    r = geometry::register_pelvis(p.bones, p.views);
    benchmark::DoNotOptimize(r);
  }
  state.counters["rounds"] = r.rounds;
  state.counters["found"] = r.found ? 1 : 0;
}
BENCHMARK(BM_PelvisRegistration)->Unit(benchmark::kMillisecond);

// The oblique view mirrored: every turn is matched, and the mirror found.
void BM_BoneOrientationCheck(benchmark::State& state) {
  const Problem& p = problem();
  const geometry::RayCaster caster(p.bones);
  const geometry::PelvisView& oblique = p.views[1];
  const geometry::PelvisView mirrored{oblique.P_ct, node::turned_image(oblique.frame, {0, true}), "LAO 35"};
  node::BoneOrientationCheck c;
  for (auto _ : state) {
    c = node::check_bone_orientation(caster, mirrored, {});
    benchmark::DoNotOptimize(c);
  }
  state.counters["found_mirror"] = c.better && c.better->first == node::PictureTurn{0, true} ? 1 : 0;
}
BENCHMARK(BM_BoneOrientationCheck)->Unit(benchmark::kMillisecond);

}  // namespace
