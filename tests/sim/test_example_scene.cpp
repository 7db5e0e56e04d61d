#include "evar/sim/example_scene.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <numbers>
#include <stdexcept>
#include <string>

#include "evar/geometry/closest_point.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/geometry/triangle_mesh.hpp"
#include "evar/sim/tube_mesh.hpp"

namespace {

using evar::geometry::TriangleMesh;
using evar::sim::ExampleScene;
using evar::sim::ExampleSceneParams;
using Points = std::vector<Eigen::Vector3d>;

const ExampleScene& default_scene() {
  static const ExampleScene scene = evar::sim::make_example_scene();
  return scene;
}

// Generalized winding number (sum of signed solid angles, Van Oosterom-Strackee): ~1 inside
// a closed outward mesh, ~0 outside, independent of ray-casting corner cases.
double winding_number(const TriangleMesh& mesh, const Eigen::Vector3d& p) {
  double total = 0.0;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)).transpose() - p;
    const Eigen::Vector3d b = mesh.V.row(mesh.F(f, 1)).transpose() - p;
    const Eigen::Vector3d c = mesh.V.row(mesh.F(f, 2)).transpose() - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    total += 2.0 * std::atan2(a.dot(b.cross(c)), la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la);
  }
  return total / (4.0 * std::numbers::pi);
}

bool closed_and_oriented(const TriangleMesh& mesh) {
  std::map<std::pair<int, int>, int> edges;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int c = 0; c < 3; ++c) ++edges[{mesh.F(f, c), mesh.F(f, (c + 1) % 3)}];
  return std::all_of(edges.begin(), edges.end(), [&](const auto& e) {
    return e.second == 1 && edges.contains({e.first.second, e.first.first});
  });
}

// Sum of the turning angles (rad) between consecutive segments.
double total_turning(const Points& p) {
  double sum = 0.0;
  for (std::size_t i = 1; i + 1 < p.size(); ++i) {
    const Eigen::Vector3d u = (p[i] - p[i - 1]).normalized(), v = (p[i + 1] - p[i]).normalized();
    sum += std::atan2(u.cross(v).norm(), u.dot(v));
  }
  return sum;
}

// Points 1 mm apart in arc length along the smooth curve: chords are shorter by about
// kappa^2 / 24 mm, under 1e-3 for these curvatures.
void expect_one_mm_spacing(const Points& p, const std::string& what) {
  ASSERT_GE(p.size(), 2u) << what;
  for (std::size_t i = 1; i + 1 < p.size(); ++i) ASSERT_NEAR((p[i] - p[i - 1]).norm(), 1.0, 1e-3) << what << " " << i;
  EXPECT_LE((p.back() - p[p.size() - 2]).norm(), 1.0 + 1e-9) << what;
}

TEST(ExampleScene, HasAortaAndBothIliacsAsClosedOutwardMeshesAtTheRequestedResolution) {
  const auto& scene = default_scene();
  ASSERT_EQ(scene.vessels.size(), 3u);
  EXPECT_EQ(scene.vessels[0].name, "aorta");
  EXPECT_EQ(scene.vessels[0].kind, evar::geometry::VesselKind::Aorta);
  EXPECT_EQ(scene.vessels[1].name, "iliac_left");
  EXPECT_EQ(scene.vessels[2].name, "iliac_right");
  EXPECT_EQ(scene.vessels[2].kind, evar::geometry::VesselKind::Iliac);
  EXPECT_NEAR(static_cast<double>(scene.vessel("aorta").mesh.V.rows()), 7500.0, 7500.0 * 0.02);
  EXPECT_NEAR(static_cast<double>(scene.vessel("iliac_left").mesh.V.rows()), 3500.0, 3500.0 * 0.02);
  EXPECT_NEAR(static_cast<double>(scene.vessel("iliac_right").mesh.V.rows()), 3500.0, 3500.0 * 0.02);
  for (const auto& v : scene.vessels) {
    EXPECT_TRUE(closed_and_oriented(v.mesh)) << v.name;
    EXPECT_GT(evar::geometry::enclosed_volume(v.mesh), 0.0) << v.name;
    EXPECT_NO_THROW(evar::geometry::validate_mesh(v.mesh, v.name));
  }
  EXPECT_THROW(static_cast<void>(scene.vessel("renal")), std::out_of_range);
}

TEST(ExampleScene, ResolutionFollowsTheVertexTargets) {
  ExampleSceneParams params;
  params.aorta_vertices = 30000;
  params.iliac_vertices = 1000;
  const auto scene = evar::sim::make_example_scene(params);
  EXPECT_NEAR(static_cast<double>(scene.vessel("aorta").mesh.V.rows()), 30000.0, 300.0);
  EXPECT_NEAR(static_cast<double>(scene.vessel("iliac_left").mesh.V.rows()), 1000.0, 20.0);
}

TEST(ExampleScene, SameSeedGivesBitIdenticalSceneAndOtherSeedsVary) {
  const auto again = evar::sim::make_example_scene();
  const auto& scene = default_scene();
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    EXPECT_TRUE((again.vessels[i].mesh.V.array() == scene.vessels[i].mesh.V.array()).all());
    EXPECT_TRUE((again.vessels[i].mesh.F.array() == scene.vessels[i].mesh.F.array()).all());
    EXPECT_EQ(again.vessels[i].centerline, scene.vessels[i].centerline);
  }
  EXPECT_EQ(again.device, scene.device);
  ASSERT_EQ(again.landmarks.size(), scene.landmarks.size());
  for (std::size_t i = 0; i < scene.landmarks.size(); ++i)
    EXPECT_EQ(again.landmarks[i].position_lps, scene.landmarks[i].position_lps);

  ExampleSceneParams other;
  other.seed = 2;
  const auto varied = evar::sim::make_example_scene(other);
  EXPECT_NE(varied.vessel("aorta").centerline, scene.vessel("aorta").centerline);
  // Without variation the seed does not matter.
  ExampleSceneParams nominal;
  nominal.variation = 0.0;
  ExampleSceneParams nominal2 = nominal;
  nominal2.seed = 99;
  EXPECT_EQ(evar::sim::make_example_scene(nominal).device, evar::sim::make_example_scene(nominal2).device);
}

TEST(ExampleScene, CenterlinesRunProximalToDistalEveryMillimetreInLps) {
  const auto& scene = default_scene();
  const auto& aorta = scene.vessel("aorta");
  EXPECT_NEAR(aorta.centerline.front().z(), 140.0, 1e-9);
  EXPECT_EQ(aorta.centerline.back(), Eigen::Vector3d::Zero());  // bifurcation at the origin
  for (const auto& name : {"iliac_left", "iliac_right"}) {
    const auto& iliac = scene.vessel(name);
    EXPECT_NEAR(iliac.centerline.front().z(), 8.0, 1e-9) << name;
    EXPECT_NEAR(iliac.centerline.back().z(), -140.0, 1e-9) << name;
    EXPECT_EQ(iliac.radii_mm.size(), iliac.centerline.size());
    EXPECT_NEAR(iliac.radii_mm.front(), 6.0, 1e-12);
    EXPECT_NEAR(iliac.radii_mm.back(), 4.5, 1e-12);
    expect_one_mm_spacing(iliac.centerline, name);
  }
  expect_one_mm_spacing(aorta.centerline, "aorta");
  // Patient left is +x.
  EXPECT_GT(scene.vessel("iliac_left").centerline.back().x(), 40.0);
  EXPECT_LT(scene.vessel("iliac_right").centerline.back().x(), -40.0);
  // The aneurysm: fusiform sac of ~25 mm radius around z ~ 60 on a ~10-12 mm aorta.
  const auto widest = std::max_element(aorta.radii_mm.begin(), aorta.radii_mm.end()) - aorta.radii_mm.begin();
  EXPECT_NEAR(aorta.radii_mm[static_cast<std::size_t>(widest)], 25.0, 2.0 + 1e-9);
  EXPECT_NEAR(aorta.centerline[static_cast<std::size_t>(widest)].z(), 60.0, 4.0 + 1.0);
  EXPECT_NEAR(aorta.radii_mm.front(), 11.5, 1e-9);
  EXPECT_NEAR(aorta.radii_mm.back(), 9.5, 1e-9);
}

TEST(ExampleScene, CenterlinesLieInsideTheirMeshesAndIliacsStartInsideTheAorta) {
  const auto& scene = default_scene();
  for (const auto& v : scene.vessels) {
    // The end points are the cap centres, on the surface; all others are inside.
    for (std::size_t i = 1; i + 1 < v.centerline.size(); ++i)
      ASSERT_NEAR(winding_number(v.mesh, v.centerline[i]), 1.0, 1e-6) << v.name << " point " << i;
  }
  const auto& aorta = scene.vessel("aorta").mesh;
  for (const auto& name : {"iliac_left", "iliac_right"})
    EXPECT_NEAR(winding_number(aorta, scene.vessel(name).centerline.front()), 1.0, 1e-6) << name;
}

TEST(ExampleScene, LandmarksLieExactlyOnTheirVesselSurfacesAtTheirOstia) {
  const auto& scene = default_scene();
  const std::map<std::string, std::string> vessel_of{{"renal_left", "aorta"},
                                                     {"renal_right", "aorta"},
                                                     {"internal_iliac_left", "iliac_left"},
                                                     {"internal_iliac_right", "iliac_right"}};
  ASSERT_EQ(scene.landmarks.size(), vessel_of.size());
  for (const auto& l : scene.landmarks) {
    ASSERT_TRUE(vessel_of.contains(l.label)) << l.label;
    const auto& vessel = scene.vessel(vessel_of.at(l.label));
    EXPECT_LT(evar::geometry::closest_point_on_mesh(vessel.mesh, l.position_lps).distance_mm, 1e-6) << l.label;
    const auto proj = evar::geometry::project_onto(vessel.centerline, l.position_lps);
    const Eigen::Vector3d offset = l.position_lps - proj.point;
    const bool left = l.label.ends_with("_left");
    if (l.label.starts_with("renal")) {
      EXPECT_NEAR(l.position_lps.z(), 110.0, 3.0) << l.label;
      EXPECT_GT(left ? offset.x() : -offset.x(), 0.9 * offset.norm()) << l.label;  // lateral
    } else {
      EXPECT_NEAR(proj.arc_length_mm, 55.0, 2.0) << l.label;
      EXPECT_GT(offset.y(), 0.3 * offset.norm()) << l.label;                     // posterior
      EXPECT_GT(left ? -offset.x() : offset.x(), 0.3 * offset.norm()) << l.label;  // medial
    }
  }
}

TEST(ExampleScene, DeviceRunsFromTheRightIliacDistalEndToATipInTheAorta) {
  const auto& scene = default_scene();
  const auto& device = scene.device;
  EXPECT_EQ(device.back(), scene.vessel("iliac_right").centerline.back());
  EXPECT_NEAR(device.front().z(), 100.0, 1e-9);
  EXPECT_NEAR(winding_number(scene.vessel("aorta").mesh, device.front()), 1.0, 1e-6);
  EXPECT_DOUBLE_EQ(scene.device_thickness_mm, 0.9);
  expect_one_mm_spacing(device, "device");
  // Monotone descent: it never doubles back.
  for (std::size_t i = 1; i < device.size(); ++i) ASSERT_LT(device[i].z(), device[i - 1].z()) << i;
}

TEST(ExampleScene, StiffDeviceLeavesTheUndeformedRightIliacByMoreThanThreeMillimetres) {
  const auto& scene = default_scene();
  const auto& iliac = scene.vessel("iliac_right");
  // Straighter than the vessel it runs in.
  EXPECT_LT(total_turning(scene.device), 0.5 * total_turning(iliac.centerline));
  // Independent of the reported figures: the device points below the bifurcation that lie
  // outside the iliac mesh, and how far outside its surface they are.
  double worst = 0.0;
  for (const auto& p : scene.device) {
    if (p.z() > -10.0 || winding_number(iliac.mesh, p) > 0.5) continue;
    worst = std::max(worst, evar::geometry::closest_point_on_mesh(iliac.mesh, p).distance_mm);
  }
  EXPECT_GE(worst, 3.0);
  EXPECT_LE(worst, 9.0);
  // The reported clearance agrees (it is measured against the smooth tube, not the mesh).
  ASSERT_EQ(scene.device_clearance.size(), 3u);
  const auto& reported = scene.device_clearance[2];
  EXPECT_EQ(reported.vessel, "iliac_right");
  EXPECT_NEAR(reported.max_outside_mm, worst, 0.5);
  EXPECT_GT(reported.length_outside_mm, 20.0);
  const auto again = evar::sim::measure_device_clearance(scene.device, iliac.centerline, iliac.radii_mm);
  EXPECT_EQ(again.max_outside_mm, reported.max_outside_mm);
  EXPECT_EQ(again.length_outside_mm, reported.length_outside_mm);
  // In the aorta it stays within a few millimetres of the wall.
  EXPECT_LT(scene.device_clearance[0].max_outside_mm, 5.0);
}

TEST(DeviceClearance, MeasuresDistanceBeyondTheRadiusAndTheLengthOutside) {
  const Points centerline{{0, 0, 0}, {0, 0, 100}};
  const std::vector<double> radii{5.0, 5.0};
  // Runs parallel at 3 mm (inside), then 8 mm (outside by 3) for 40 mm, then past the end.
  Points device;
  for (int z = 0; z <= 40; ++z) device.emplace_back(3.0, 0.0, z);
  for (int z = 40; z <= 80; ++z) device.emplace_back(8.0, 0.0, z);
  device.emplace_back(8.0, 0.0, 150.0);
  const auto c = evar::sim::measure_device_clearance(device, centerline, radii);
  EXPECT_NEAR(c.max_outside_mm, 3.0, 1e-12);
  // 40 mm along x = 8, plus the part of the 5 mm step from x = 3 to 8 beyond r = 5 (3/5).
  EXPECT_NEAR(c.length_outside_mm, 40.0 + 3.0, 1e-9);
  EXPECT_THROW(evar::sim::measure_device_clearance(device, centerline, {5.0}), std::invalid_argument);
}

TEST(ExampleScene, RejectsParametersThatCannotGiveAnAnatomy) {
  ExampleSceneParams p;
  p.aneurysm_max_radius_mm = 5.0;
  p.variation = 0.0;
  EXPECT_THROW(evar::sim::make_example_scene(p), std::invalid_argument);
  p = {};
  p.device_tip_z_mm = 200.0;
  EXPECT_THROW(evar::sim::make_example_scene(p), std::invalid_argument);
  p = {};
  p.iliac_vertices = 10;
  EXPECT_THROW(evar::sim::make_example_scene(p), std::invalid_argument);
}

std::filesystem::path fresh_dir(const std::string& name) {
  const auto dir = std::filesystem::path(::testing::TempDir()) / ("evar_sim_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  return dir;
}

TEST(ExampleScene, WrittenDirectoryHasEveryFileAndReloadsAsTheSameScene) {
  const auto& scene = default_scene();
  const auto dir = fresh_dir("scene_stl");
  evar::sim::write_example_scene(scene, dir);
  for (const char* f : {"scene.json", "aorta.stl", "iliac_left.stl", "iliac_right.stl",
                        "aorta.centerline.mrk.json", "iliac_left.centerline.mrk.json",
                        "iliac_right.centerline.mrk.json", "landmarks.mrk.json", "device.mrk.json"})
    EXPECT_TRUE(std::filesystem::is_regular_file(dir / f)) << f;

  const auto loaded = evar::geometry::load_scene(dir / "scene.json");
  ASSERT_EQ(loaded.vessels.size(), 3u);
  EXPECT_DOUBLE_EQ(loaded.device_thickness_mm, 0.9);
  for (std::size_t i = 0; i < 3; ++i) {
    const auto& a = scene.vessels[i];
    const auto& b = loaded.vessels[i];
    EXPECT_EQ(b.name, a.name);
    EXPECT_EQ(b.kind, a.kind);
    // STL stores float triangles; welding restores the shared vertices in order of use.
    ASSERT_EQ(b.mesh.mesh.V.rows(), a.mesh.V.rows()) << a.name;
    ASSERT_EQ(b.mesh.mesh.F.rows(), a.mesh.F.rows()) << a.name;
    for (Eigen::Index f = 0; f < a.mesh.F.rows(); ++f)
      for (int c = 0; c < 3; ++c)
        ASSERT_LT((b.mesh.mesh.V.row(b.mesh.mesh.F(f, c)) - a.mesh.V.row(a.mesh.F(f, c))).norm(), 1e-4);
    ASSERT_EQ(b.centerline.size(), a.centerline.size());
    for (std::size_t k = 0; k < a.centerline.size(); ++k) ASSERT_LT((b.centerline[k] - a.centerline[k]).norm(), 1e-6);
  }
  ASSERT_EQ(loaded.landmarks.size(), scene.landmarks.size());
  for (std::size_t k = 0; k < scene.landmarks.size(); ++k) {
    EXPECT_EQ(loaded.landmarks[k].label, scene.landmarks[k].label);
    EXPECT_LT((loaded.landmarks[k].position_lps - scene.landmarks[k].position_lps).norm(), 1e-6);
  }
  const auto device = evar::geometry::read_curve(dir / "device.mrk.json");
  ASSERT_EQ(device.points.size(), scene.device.size());
  EXPECT_LT((device.points.front().position_lps - scene.device.front()).norm(), 1e-6);  // tip first
  EXPECT_LT((device.points.back().position_lps - scene.device.back()).norm(), 1e-6);
}

TEST(ExampleScene, MeshFormatChoosesTheFileExtension) {
  const auto dir = fresh_dir("scene_ply");
  evar::sim::write_example_scene(default_scene(), dir, evar::geometry::MeshFormat::PlyBinary);
  EXPECT_TRUE(std::filesystem::is_regular_file(dir / "aorta.ply"));
  EXPECT_FALSE(std::filesystem::exists(dir / "aorta.stl"));
  const auto loaded = evar::geometry::load_scene(dir / "scene.json");
  ASSERT_EQ(loaded.vessels.size(), 3u);
  // PLY keeps vertex order and topology.
  EXPECT_TRUE((loaded.vessels[0].mesh.mesh.F.array() == default_scene().vessels[0].mesh.F.array()).all());
}

}  // namespace
