#include <gtest/gtest.h>
#include <unistd.h>

#include <string>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <sstream>

#include "evar/geometry/closest_point.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/geometry/ray_caster.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/sim/registration_residual.hpp"
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


// The second truth physics holds the device the same way, at both difficulties, and keeps
// what it says it keeps: the aorta does not move above the renal level (its visceral and
// renal branches hold it), and no wall turns inside out.
TEST(ConformingTruth, HoldsTheDeviceAndTheAortaStaysAboveTheRenalLevel) {
  for (const Difficulty difficulty : {Difficulty::Mild, Difficulty::Paper})
    for (std::uint64_t seed = 1; seed <= 8; ++seed) {
      const auto patient = make_patient(PatientPlan{seed, difficulty, TruthPhysics::Conforming, kAorta, kIliac});
      const std::string which = std::string(to_string(difficulty)) + " seed " + std::to_string(seed);
      const auto& scene = patient.preoperative;
      std::vector<const geometry::TriangleMesh*> after;
      for (const auto& v : patient.truth.vessels) after.push_back(&v.mesh);
      EXPECT_EQ(device_points_outside(scene.device, after, scene.device_thickness_mm), "") << which;
      EXPECT_LE(patient.truth.max_intrusion_mm, 0.01) << which;
      const auto& aorta = scene.vessel("aorta");
      for (std::size_t i = 0; i < aorta.centerline.size(); ++i)
        if (aorta.centerline[i].z() > patient.params.renal_z_mm + 1.0) {
          ASSERT_EQ((patient.truth.vessels[0].centerline[i] - aorta.centerline[i]).norm(), 0.0) << which << ", point " << i;
        }
      for (std::size_t v = 0; v < scene.vessels.size(); ++v)
        EXPECT_EQ(flipped_triangles(scene.vessels[v].mesh, patient.truth.vessels[v].mesh), 0) << which << ", " << scene.vessels[v].name;
      // The renal ostia stay (within 0.01 mm: they sit at the held level, and the first
      // sections below it give way by a hair).
      for (std::size_t k = 0; k < scene.landmarks.size(); ++k)
        if (scene.landmarks[k].label.rfind("renal", 0) == 0) {
          EXPECT_LT((patient.truth.landmarks[k].position_lps - scene.landmarks[k].position_lps).norm(), 0.01) << which;
        }
    }
}

// Threaded on a straighter wire, the carrier iliac keeps its wall length when it slides
// along the wire (fold fraction 0) and is shortened to the wire's course when it folds
// (fold fraction 1); the two differ by the excess length the tortuous course had.
TEST(ConformingTruth, ASlidingIliacKeepsItsLengthAFoldingOneShortens) {
  const auto patient = make_patient(PatientPlan{5, Difficulty::Paper, TruthPhysics::Conforming, kAorta, kIliac});
  ExampleScene scene = make_example_scene(patient.params);  // the CT's anatomy, moved onto the table
  apply(patient.posture, scene);
  ASSERT_EQ(scene.device, patient.preoperative.device) << "the device lies in the anatomy on the table";
  const std::size_t carrier = patient.params.device_in_left_iliac ? 1 : 2;
  const auto length = [](const geometry::Polyline& c) { return geometry::arc_lengths(c).back(); };
  const double rest = length(scene.vessels[carrier].centerline);
  ConformingOptions slide, fold;
  slide.fold_fraction = 0.0;
  fold.fold_fraction = 1.0;
  const double slid = length(distort_by_conforming(scene, slide).vessels[carrier].centerline);
  const double folded = length(distort_by_conforming(scene, fold).vessels[carrier].centerline);
  EXPECT_NEAR(slid / rest, 1.0, 0.03);
  EXPECT_LT(folded, 0.92 * rest) << "a tortuous iliac (index " << rest << " mm of wall) straightened by the wire";
}

// A straight tube turned rigidly about a point off its axis: each section turns by the
// least rotation between its old and new tangent, which for a turn about an axis across
// the tube is the turn itself, so the whole mesh turns rigidly.
TEST(ResweepTurning, ATurnedStraightTubeTurnsItsSections) {
  geometry::Polyline line;
  for (int i = 0; i <= 80; ++i) line.push_back(Eigen::Vector3d(3.0, -2.0, 100.0 - i));
  const std::vector<double> radii(line.size(), 6.0);
  const auto mesh = tube_mesh(line, radii, tube_options_for_vertex_count(80.0, 6.0, 1500));
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  const Eigen::Vector3d pivot(10, 0, 40);
  geometry::Polyline turned;
  for (const auto& p : line) turned.push_back(R * (p - pivot) + pivot);
  const auto out = resweep_turning(mesh, line, turned);
  double worst = 0.0;
  for (Eigen::Index i = 0; i < mesh.V.rows(); ++i)
    worst = std::max(worst, (out.V.row(i).transpose() - (R * (mesh.V.row(i).transpose() - pivot) + pivot)).norm());
  EXPECT_LT(worst, 1e-9);
  // Translated only (turn = false), the sections keep their orientation: not the turned mesh.
  EXPECT_GT((resweep_turning(mesh, line, turned, false).V - out.V).cwiseAbs().maxCoeff(), 1.0);
}

TEST(ResweepTurning, SameCenterlineGivesTheMeshBackAndATranslationTranslates) {
  const auto patient = make_patient(4, kAorta, kIliac);
  const auto& v = patient.preoperative.vessel("iliac_right");
  EXPECT_LT((resweep_turning(v.mesh, v.centerline, v.centerline).V - v.mesh.V).cwiseAbs().maxCoeff(), 1e-9);
  const Eigen::Vector3d t(-3, 8, 2);
  geometry::Polyline moved;
  for (const auto& c : v.centerline) moved.push_back(c + t);
  const auto out = resweep_turning(v.mesh, v.centerline, moved);
  EXPECT_LT((out.V.rowwise() - t.transpose() - v.mesh.V).cwiseAbs().maxCoeff(), 1e-9);
}

// The paper's difficulty draws from the same seed a more tortuous anatomy and a stiffer
// wire, within the documented ranges; the mild level is the simulator as it was.
TEST(PaperDifficulty, MoreTortuousIliacsAndStifferWiresWithinTheirRanges) {
  for (std::uint64_t seed = 1; seed <= 50; ++seed) {
    const auto mild = draw_patient_params(seed), paper = draw_patient_params(seed, Difficulty::Paper);
    EXPECT_EQ(mild.aneurysm_max_radius_mm, paper.aneurysm_max_radius_mm) << "the rest of the anatomy is the seed's";
    EXPECT_GE(paper.iliac_tortuosity_x_mm, 18.0);
    EXPECT_LT(paper.iliac_tortuosity_x_mm, 38.0);
    EXPECT_GE(paper.iliac_tortuosity_y_mm, 10.0);
    EXPECT_LT(paper.iliac_tortuosity_y_mm, 24.0);
    EXPECT_GE(paper.device_stiffness_length_mm, 60.0);
    EXPECT_LT(paper.device_stiffness_length_mm, 120.0);
    EXPECT_LT(mild.device_stiffness_length_mm, 60.0);
  }
}

// The registration residual: none at the mild level; at the paper's a few degrees and about
// a millimetre, turning about the renal level, after the shift that registers the models to
// the renal arteries.
TEST(RegistrationResidual, NoneWhenMildSmallAboutTheRenalLevelAtThePapersDifficulty) {
  const Eigen::Vector3d renal(2, -5, 120);
  EXPECT_TRUE(draw_registration_residual(3, Difficulty::Mild, renal).is_identity());
  for (std::uint64_t seed = 1; seed <= 40; ++seed) {
    RegistrationResidual r = draw_registration_residual(seed, Difficulty::Paper, renal);
    EXPECT_FALSE(r.is_identity());
    EXPECT_LE(r.rotation_deg.cwiseAbs().maxCoeff(), 5.0);
    EXPECT_LE(r.translation_mm.cwiseAbs().maxCoeff(), 1.0);
    r.alignment_mm = Eigen::Vector3d(1.5, -0.5, 4.0);
    const Eigen::Matrix4d M = r.transform();
    // The preoperative renal level (renal - alignment) lands on the true one, off by the
    // translation only; a point 150 mm below moves by the lever of the rotation.
    const Eigen::Vector3d pre = renal - r.alignment_mm;
    EXPECT_LT((M.topLeftCorner<3, 3>() * pre + M.topRightCorner<3, 1>() - (renal + r.translation_mm)).norm(), 1e-9);
    const Eigen::Vector3d below = pre - Eigen::Vector3d(0, 0, 150);
    const double moved = (M.topLeftCorner<3, 3>() * below + M.topRightCorner<3, 1>() - (below + r.alignment_mm)).norm();
    EXPECT_LE(moved, 150.0 * std::sqrt(3.0) * 5.0 * std::numbers::pi / 180.0 + std::sqrt(3.0));
    EXPECT_TRUE((M.topLeftCorner<3, 3>() * M.topLeftCorner<3, 3>().transpose()).isIdentity(1e-12));
  }
}

// The pelvis on the table against the CT: nothing at or above the renal level moves, the
// whole shift applies from the bifurcation down, smoothly in between; the written device is
// the one on the table, which the truth holds.
TEST(PostureChange, NothingAboveTheRenalLevelAllBelowTheBifurcation) {
  EXPECT_TRUE(draw_posture_change(9, Difficulty::Mild, 120.0).is_none());
  const PostureChange c = draw_posture_change(9, Difficulty::Paper, 120.0);
  ASSERT_FALSE(c.is_none());
  EXPECT_LE(std::abs(c.pelvis_shift_mm.z()), 12.0);
  EXPECT_EQ(c.shift_at({0, 0, 121.0}), Eigen::Vector3d::Zero());
  EXPECT_EQ(c.shift_at({5, 3, 120.0}), Eigen::Vector3d::Zero());
  EXPECT_LT((c.shift_at({0, 0, -40.0}) - c.pelvis_shift_mm).norm(), 1e-12);
  EXPECT_LT((c.shift_at({0, 0, 60.0}) - 0.5 * c.pelvis_shift_mm).norm(), 1e-12);
  const auto patient = make_patient(PatientPlan{9, Difficulty::Paper, TruthPhysics::Beam, kAorta, kIliac});
  const auto plain = make_example_scene(patient.params);
  ASSERT_EQ(plain.device.size(), patient.preoperative.device.size());
  for (std::size_t k = 0; k < plain.device.size(); ++k)
    ASSERT_LT((patient.preoperative.device[k] - plain.device[k] - patient.posture.shift_at(plain.device[k])).norm(), 1e-9) << k;
}

// The skeleton follows the posture as the vessels at its height do: the pelvis's bones (the
// femoral heads, 150 mm below the bifurcation) by the whole shift, a vertebra above the renal
// level not at all, one on the ramp by the ramp's share; sizes and densities unchanged.
TEST(PostureChange, MovesTheBonesWithTheAnatomyAtTheirHeight) {
  PostureChange c;
  c.pelvis_shift_mm = {1.0, -2.0, 9.0};
  c.renal_z_mm = 120.0;
  const BodyPhantom before = default_body_phantom(4);
  BodyPhantom after = before;
  apply(c, after);
  ASSERT_EQ(after.parts.size(), before.parts.size());
  int pelvis = 0, above = 0, ramp = 0;
  for (std::size_t k = 0; k < before.parts.size(); ++k) {
    const Eigen::Vector3d x = before.parts[k].centre_mm;
    EXPECT_LT((after.parts[k].centre_mm - x - c.shift_at(x)).norm(), 1e-12) << k;
    EXPECT_EQ(after.parts[k].semi_axes_mm, before.parts[k].semi_axes_mm);
    EXPECT_EQ(after.parts[k].mu_per_mm, before.parts[k].mu_per_mm);
    if (x.z() <= 0.0) pelvis += (after.parts[k].centre_mm - x - c.pelvis_shift_mm).norm() < 1e-12;
    if (x.z() >= 120.0) above += after.parts[k].centre_mm == x;
    if (x.z() > 10.0 && x.z() < 110.0) ramp += (after.parts[k].centre_mm - x).norm() > 0.1 && (after.parts[k].centre_mm - x).norm() < 9.2;
  }
  EXPECT_GE(pelvis, 8);  // sacrum, two iliac wings (two shells each), two femoral heads, two rami
  EXPECT_GE(above, 1);   // L2 and L1 lie at 124 and 157 mm
  EXPECT_GE(ramp, 1);
  BodyPhantom unmoved = before;
  apply(PostureChange{}, unmoved);
  for (std::size_t k = 0; k < before.parts.size(); ++k) EXPECT_EQ(unmoved.parts[k].centre_mm, before.parts[k].centre_mm);
}

// The CT's pelvis as a bone segmentation gives it: closed, outward, each bone's volume that of
// its ellipsoid (to the icosphere's 1 %), written beside the patient's vessels and named by its
// scene; the truth's pelvis lies where the posture put it.
TEST(PelvisMesh, ClosedOutwardBonesWrittenWithThePatient) {
  const BodyPhantom body = default_body_phantom();
  const geometry::TriangleMesh bones = pelvis_mesh(body);
  EXPECT_TRUE(geometry::is_closed(bones));
  const double volume = geometry::enclosed_volume(bones);
  double expected = 0.0;
  int parts = 0;
  for (std::size_t k = body.pelvis_begin; k < body.pelvis_end; ++k)
    if (body.parts[k].mu_per_mm > 0.0) expected += 4.0 / 3.0 * std::numbers::pi * body.parts[k].semi_axes_mm.prod(), ++parts;
  EXPECT_EQ(parts, 7);  // sacrum, and per side the iliac wing, femoral head and pubic ramus
  EXPECT_EQ(bones.V.rows(), parts * 642);
  EXPECT_NEAR(volume, expected, 0.015 * expected);

  const auto patient = make_patient(PatientPlan{9, Difficulty::Paper, TruthPhysics::Beam, kAorta, kIliac});
  const auto dir = std::filesystem::path(testing::TempDir()) / ("evar_pelvis_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  write_patient(patient, dir);
  const geometry::Scene scene = geometry::load_scene(dir / "scene.json");
  ASSERT_EQ(scene.pelvis.V.rows(), bones.V.rows());
  // STL welds (its own vertex order) and keeps single precision: compare where the bones lie.
  const Eigen::RowVector3d centre = bones.V.colwise().mean();
  EXPECT_LT((scene.pelvis.V.colwise().mean() - centre).norm(), 1e-3);
  EXPECT_LT((scene.pelvis.V.colwise().maxCoeff() - bones.V.colwise().maxCoeff()).norm(), 1e-3);
  const geometry::Scene truth = geometry::load_scene(dir / "truth" / "scene.json");
  ASSERT_EQ(truth.pelvis.V.rows(), bones.V.rows());
  const Eigen::RowVector3d moved = truth.pelvis.V.colwise().mean() - centre;
  EXPECT_LT((moved.transpose() - patient.posture.pelvis_shift_mm).norm(), 1e-3);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace evar::sim
