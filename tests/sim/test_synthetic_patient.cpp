#include <gtest/gtest.h>
#include <unistd.h>

#include <string>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "evar/geometry/closest_point.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/geometry/ray_caster.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/sim/synthetic_patient.hpp"
#include "evar/sim/tube_mesh.hpp"

namespace evar::sim {
namespace {

constexpr int kAorta = 3000, kIliac = 1500;  // coarse meshes keep the tests quick

// Device points neither inside one of the meshes (ray parity, Embree) nor within
// `slack_mm` of a wall, listed as " index/count (distance)"; empty when all are in.
std::string device_points_outside(const std::vector<Eigen::Vector3d>& device,
                                  const std::vector<const geometry::TriangleMesh*>& meshes, double slack_mm) {
  std::vector<geometry::RayCaster> casters;
  for (const auto* m : meshes) casters.emplace_back(*m, geometry::RayCaster::BuildQuality::Low);
  std::string outside;
  for (std::size_t i = 0; i < device.size(); ++i) {
    bool in = false;
    for (const auto& c : casters) in = in || c.contains(device[i]);
    if (in) continue;
    double gap = 1e9;
    for (const auto* m : meshes) gap = std::min(gap, geometry::closest_point_on_mesh(*m, device[i]).distance_mm);
    if (gap > slack_mm) {
      std::ostringstream item;
      item << ' ' << i << '/' << device.size() << " (" << gap << " mm out)";
      outside += item.str();
    }
  }
  return outside;
}

int flipped_triangles(const geometry::TriangleMesh& before, const geometry::TriangleMesh& after) {
  int flipped = 0;
  for (Eigen::Index f = 0; f < before.F.rows(); ++f) {
    const auto normal = [&](const geometry::TriangleMesh& m) {
      const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
      return Eigen::Vector3d((b - a).cross(c - a));
    };
    flipped += normal(before).dot(normal(after)) <= 0.0 ? 1 : 0;
  }
  return flipped;
}

TEST(Resweep, SameCenterlineGivesTheMeshBack) {
  const auto patient = make_patient(3, kAorta, kIliac);
  for (const auto& v : patient.preoperative.vessels) {
    const auto again = resweep(v.mesh, v.centerline, v.centerline);
    EXPECT_LT((again.V - v.mesh.V).cwiseAbs().maxCoeff(), 1e-9) << v.name;
  }
}

TEST(Resweep, TranslatedCenterlineTranslatesTheMesh) {
  const auto patient = make_patient(4, kAorta, kIliac);
  const auto& v = patient.preoperative.vessel("iliac_left");
  const Eigen::Vector3d t(5, -7, 11);
  geometry::Polyline moved;
  for (const auto& c : v.centerline) moved.push_back(c + t);
  const auto out = resweep(v.mesh, v.centerline, moved);
  for (Eigen::Index i = 0; i < v.mesh.V.rows(); ++i)
    ASSERT_LT((out.V.row(i).transpose() - (v.mesh.V.row(i).transpose() + t)).norm(), 1e-9) << "vertex " << i;
}

TEST(SyntheticPatient, SameSeedSameBytes) {
  const auto a = make_patient(11, kAorta, kIliac), b = make_patient(11, kAorta, kIliac);
  ASSERT_EQ(a.truth.vessels.size(), b.truth.vessels.size());
  for (std::size_t i = 0; i < a.truth.vessels.size(); ++i) {
    EXPECT_TRUE(a.preoperative.vessels[i].mesh.V == b.preoperative.vessels[i].mesh.V);
    EXPECT_TRUE(a.truth.vessels[i].mesh.V == b.truth.vessels[i].mesh.V);
  }
  EXPECT_EQ(a.preoperative.device, b.preoperative.device);
  const auto c = make_patient(12, kAorta, kIliac);
  EXPECT_FALSE(a.preoperative.vessels[0].mesh.V.rows() == c.preoperative.vessels[0].mesh.V.rows() &&
               a.preoperative.vessels[0].mesh.V == c.preoperative.vessels[0].mesh.V);
}

// The property the whole evaluation rests on: the device the truth was made for lies in
// the distorted lumen (checked here independently of make_patient's own check). Where the
// section model and the swept meshes disagree, the sections whose walls miss the device
// are pushed in extra passes (seed 7 at the default resolution: test_cli.cpp); a seed the
// model still could not resolve would be refused with the seed named.
TEST(SyntheticPatient, TruthHoldsTheDeviceOrTheSeedIsRefused) {
  int made = 0, refused = 0;
  for (std::uint64_t seed = 1; seed <= 16; ++seed) {
    SyntheticPatient patient;
    try {
      patient = make_patient(seed, kAorta, kIliac);
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("seed " + std::to_string(seed)), std::string::npos) << e.what();
      ++refused;
      continue;
    }
    ++made;
    const auto& scene = patient.preoperative;
    std::vector<const geometry::TriangleMesh*> before, after;
    for (const auto& v : scene.vessels) before.push_back(&v.mesh);
    for (const auto& v : patient.truth.vessels) after.push_back(&v.mesh);
    EXPECT_EQ(device_points_outside(scene.device, after, scene.device_thickness_mm), "") << "seed " << seed;
    EXPECT_LE(patient.truth.max_intrusion_mm, 0.01);
    const auto& carrier = patient.truth.vessels[patient.params.device_in_left_iliac ? 1 : 2];
    EXPECT_EQ(carrier.name, patient.truth.carrier);
    // A device the preoperative lumen already holds hardly moves it; one that leaves it
    // moves it by millimetres, not centimetres beyond reason.
    if (device_points_outside(scene.device, before, scene.device_thickness_mm).empty())
      EXPECT_LT(carrier.max_displacement_mm, 2.0) << "seed " << seed;
    else
      EXPECT_GT(carrier.max_displacement_mm, 0.5) << "seed " << seed;
    EXPECT_LT(carrier.max_displacement_mm, 40.0) << "seed " << seed;
    for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
      // Topology and order kept, no fold, tethered ends in place.
      EXPECT_EQ(patient.truth.vessels[i].mesh.F, scene.vessels[i].mesh.F);
      EXPECT_EQ(flipped_triangles(scene.vessels[i].mesh, patient.truth.vessels[i].mesh), 0)
          << "seed " << seed << " " << scene.vessels[i].name;
      const auto& tethered = scene.vessels[i].kind == geometry::VesselKind::Aorta ? 0 : scene.vessels[i].centerline.size() - 1;
      EXPECT_LT((patient.truth.vessels[i].centerline[tethered] - scene.vessels[i].centerline[tethered]).norm(), 0.05);
    }
    ASSERT_EQ(patient.truth.landmarks.size(), scene.landmarks.size());
    for (std::size_t k = 0; k < scene.landmarks.size(); ++k)
      EXPECT_EQ(patient.truth.landmarks[k].label, scene.landmarks[k].label);
  }
  EXPECT_EQ(made, 16) << refused << " of 16 seeds refused";
}

TEST(SyntheticPatient, DrawnAnatomyStaysInItsRanges) {
  for (std::uint64_t seed = 1; seed <= 200; ++seed) {
    const auto p = draw_patient_params(seed);
    EXPECT_GE(2.0 * p.aneurysm_max_radius_mm, 50.0);
    EXPECT_LE(2.0 * p.aneurysm_max_radius_mm, 75.0);
    EXPECT_GE(p.renal_z_mm - (p.aneurysm_centre_z_mm + 0.5 * p.aneurysm_length_mm), 15.0 - 1e-9);
    EXPECT_GE(p.aneurysm_centre_z_mm - 0.5 * p.aneurysm_length_mm, 12.0 - 1e-9);
    EXPECT_LT(p.aorta_radius_bifurcation_mm, p.aorta_radius_top_mm);
    EXPECT_LT(p.iliac_radius_distal_mm, p.iliac_radius_proximal_mm);
    EXPECT_GT(p.device_tip_z_mm, p.renal_z_mm - 10.0 - 1e-9);
  }
}

TEST(SyntheticPatient, WrittenTruthIsALoadableSceneWithTheSameVertexOrder) {
  const auto dir = std::filesystem::path(testing::TempDir()) / ("evar_patient_7_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  const auto patient = make_patient(7, kAorta, kIliac);
  write_patient(patient, dir);
  const auto pre = geometry::load_scene(dir / "scene.json");
  const auto truth = geometry::load_scene(dir / "truth" / "scene.json");
  ASSERT_EQ(pre.vessels.size(), truth.vessels.size());
  for (std::size_t i = 0; i < pre.vessels.size(); ++i) {
    EXPECT_EQ(pre.vessels[i].mesh.mesh.V.rows(), truth.vessels[i].mesh.mesh.V.rows());
    EXPECT_EQ(pre.vessels[i].mesh.mesh.F, truth.vessels[i].mesh.mesh.F);
  }
  EXPECT_TRUE(std::filesystem::exists(dir / "patient.json"));
  EXPECT_TRUE(std::filesystem::exists(dir / "device.mrk.json"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace evar::sim
