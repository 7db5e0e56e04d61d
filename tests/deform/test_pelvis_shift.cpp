// The pelvis's displacement against models registered to the renal arteries, carried into
// the scene before it is bent (deform/pelvis_shift.hpp).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <limits>

#include "evar/base/input_error.hpp"
#include "evar/deform/pelvis_shift.hpp"
#include "evar/sim/example_scene.hpp"

using namespace evar;

namespace {

const geometry::Scene& example_scene() {
  static const geometry::Scene scene = sim::to_scene(sim::make_example_scene({}));
  return scene;
}

const geometry::Vessel& aorta_of(const geometry::Scene& s) {
  for (const auto& v : s.vessels)
    if (v.kind == geometry::VesselKind::Aorta) return v;
  throw std::logic_error("no aorta");
}

Eigen::Vector3d landmark(const geometry::Scene& s, const std::string& label) {
  for (const auto& lm : s.landmarks)
    if (lm.label == label) return lm.position_lps;
  throw std::logic_error("no landmark " + label);
}

// The centerline point nearest to p, found by sampling every 0.05 mm (no shared code).
Eigen::Vector3d nearest_by_sampling(const std::vector<Eigen::Vector3d>& c, const Eigen::Vector3d& p) {
  Eigen::Vector3d best = c.front();
  for (std::size_t i = 0; i + 1 < c.size(); ++i) {
    const int n = std::max(1, static_cast<int>((c[i + 1] - c[i]).norm() / 0.05));
    for (int k = 0; k <= n; ++k) {
      const Eigen::Vector3d q = c[i] + (c[i + 1] - c[i]) * (static_cast<double>(k) / n);
      if ((q - p).norm() < (best - p).norm()) best = q;
    }
  }
  return best;
}

}  // namespace

TEST(PelvisShift, RampsFromTheRenalLevelToTheBifurcationAlongTheAorta) {
  const auto& scene = example_scene();
  const Eigen::Vector3d shift(2.0, -1.0, -10.0);
  const auto ps = deform::pelvis_shift_for(scene, shift);
  const auto& aorta = aorta_of(scene);
  // The ramp's ends: the centerline's point nearest the renal ostia, and its distal end.
  const Eigen::Vector3d renal_mean = 0.5 * (landmark(scene, "renal_left") + landmark(scene, "renal_right"));
  EXPECT_LT((ps.renal_point_mm - nearest_by_sampling(aorta.centerline, renal_mean)).norm(), 0.05);
  EXPECT_EQ(ps.bifurcation_point_mm, aorta.centerline.back());
  const Eigen::Vector3d axis = ps.bifurcation_point_mm - ps.renal_point_mm;
  const auto at = [&](double f) { return ps.displacement_at(ps.renal_point_mm + f * axis); };
  EXPECT_LT(at(0.0).norm(), 1e-12);
  EXPECT_LT(at(-0.5).norm(), 1e-12);  // above the renal level: nothing
  EXPECT_LT((at(1.0) - shift).norm(), 1e-12);
  EXPECT_LT((at(2.0) - shift).norm(), 1e-12);  // the pelvis: all of it
  EXPECT_LT((at(0.5) - 0.5 * shift).norm(), 1e-12);
  // Smooth at both ends: a hundredth of the way in moves by 3 parts in 10 000, not 1 in 100.
  EXPECT_NEAR(at(0.01).norm() / shift.norm(), 0.01 * 0.01 * (3.0 - 0.02), 1e-9);
  EXPECT_NEAR((shift - at(0.99)).norm() / shift.norm(), 0.01 * 0.01 * (3.0 - 0.02), 1e-9);
  // Off the axis only the place along it counts.
  const Eigen::Vector3d side = axis.unitOrthogonal() * 40.0;
  EXPECT_LT((ps.displacement_at(ps.renal_point_mm + 0.3 * axis + side) - at(0.3)).norm(), 1e-12);
}

TEST(PelvisShift, MovesEveryVertexCenterlineAndLandmarkByItsDisplacementAndDropsTheProxyFiles) {
  geometry::Scene scene = example_scene();
  for (auto& v : scene.vessels) v.proxy_path = "made_for_the_unmoved_mesh.proxy.ply";
  const Eigen::Vector3d shift(0.0, 3.0, -8.0);
  const auto ps = deform::pelvis_shift_for(scene, shift);
  deform::apply(ps, scene);
  const auto& before = example_scene();
  for (std::size_t k = 0; k < scene.vessels.size(); ++k) {
    const auto& V0 = before.vessels[k].mesh.mesh.V;
    const auto& V1 = scene.vessels[k].mesh.mesh.V;
    ASSERT_EQ(V0.rows(), V1.rows());
    for (Eigen::Index i = 0; i < V0.rows(); ++i) {
      const Eigen::Vector3d x = V0.row(i).transpose();
      ASSERT_LT((V1.row(i).transpose() - (x + ps.displacement_at(x))).norm(), 1e-12) << scene.vessels[k].name << " " << i;
    }
    EXPECT_EQ(scene.vessels[k].mesh.mesh.F, before.vessels[k].mesh.mesh.F);
    for (std::size_t i = 0; i < before.vessels[k].centerline.size(); ++i) {
      const Eigen::Vector3d c = before.vessels[k].centerline[i];
      ASSERT_LT((scene.vessels[k].centerline[i] - (c + ps.displacement_at(c))).norm(), 1e-12);
    }
    EXPECT_TRUE(scene.vessels[k].proxy_path.empty()) << scene.vessels[k].name;
  }
  // The internal iliac ostia lie in the pelvis and move with it; the renal ostia stay
  // (they sit on the renal level, a radius off the axis).
  for (const char* label : {"internal_iliac_left", "internal_iliac_right"})
    EXPECT_LT((landmark(scene, label) - landmark(before, label) - shift).norm(), 1e-9) << label;
  for (const char* label : {"renal_left", "renal_right"})
    EXPECT_LT((landmark(scene, label) - landmark(before, label)).norm(), 0.05) << label;
}

TEST(PelvisShift, WithoutRenalLandmarksTheRampStartsAtTheAortasProximalEnd) {
  geometry::Scene scene = example_scene();
  std::erase_if(scene.landmarks, [](const geometry::ControlPoint& lm) { return lm.label.rfind("renal", 0) == 0; });
  const auto ps = deform::pelvis_shift_for(scene, Eigen::Vector3d(0.0, 0.0, 5.0));
  EXPECT_EQ(ps.renal_point_mm, aorta_of(scene).centerline.front());
}

TEST(PelvisShift, RefusesARampTooShortToBendOverAndADisplacementThatIsNotFinite) {
  geometry::Scene scene = example_scene();
  scene.file = "patient/scene.json";
  for (auto& v : scene.vessels)
    if (v.kind == geometry::VesselKind::Aorta) v.centerline = {Eigen::Vector3d(0, 0, 4), Eigen::Vector3d(0, 0, -4)};
  std::erase_if(scene.landmarks, [](const geometry::ControlPoint& lm) { return lm.label.rfind("renal", 0) == 0; });
  try {
    (void)deform::pelvis_shift_for(scene, Eigen::Vector3d(0.0, 0.0, 5.0));
    FAIL() << "an 8 mm ramp was accepted";
  } catch (const base::InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("patient/scene.json"), std::string::npos) << what;
    EXPECT_NE(what.find("8 mm apart"), std::string::npos) << what;
    EXPECT_NE(what.find("at least 10 mm"), std::string::npos) << what;
  }
  EXPECT_THROW((void)deform::pelvis_shift_for(example_scene(), Eigen::Vector3d(0.0, std::numeric_limits<double>::quiet_NaN(), 0.0)),
               base::InputError);
}
