#include <gtest/gtest.h>

#include "evar/deform/scene_deformation.hpp"
#include "evar/geometry/closest_point.hpp"
#include "evar/base/input_error.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/geometry/ray_caster.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/sim/example_scene.hpp"
#include "support/temp_dir.hpp"

using namespace evar;

namespace {

const sim::ExampleScene& example() {
  static const sim::ExampleScene ex = sim::make_example_scene({});
  return ex;
}
// Largest relative change of an edge's length between two poses of the same faces.
double worst_edge_strain(const geometry::Faces& F, const geometry::Vertices& V0, const geometry::Vertices& V) {
  double worst = 0.0;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int j = 0; j < 3; ++j) {
      const double l0 = (V0.row(F(f, j)) - V0.row(F(f, (j + 1) % 3))).norm();
      const double l1 = (V.row(F(f, j)) - V.row(F(f, (j + 1) % 3))).norm();
      worst = std::max(worst, std::abs(l1 / l0 - 1.0));
    }
  return worst;
}
}  // namespace

TEST(SceneDeformation, AfterDeformEveryDevicePointIsInsideItsVesselOrWithinDeltaDOfTheWall) {
  const auto scene = sim::to_scene(example());
  const auto out = deform::deform_scene(scene, example().device);
  EXPECT_EQ(out.device_iliac, "iliac_right");
  // Containment on the deformed meshes with their full faces (the erased aortic stump is
  // a bookkeeping step and does not change where the walls are).
  std::vector<geometry::TriangleMesh> deformed;
  std::vector<geometry::RayCaster> casters;
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    deformed.push_back({out.vessels[i].mesh.V, scene.vessels[i].mesh.mesh.F});
    casters.emplace_back(deformed.back());
  }
  const double tolerance = scene.device_thickness_mm + 0.1;  // Δd plus the 0.01 mm solver tolerance and facet error
  int outside = 0;
  double worst = 0.0;
  for (const auto& d : example().device) {
    bool ok = false;
    double nearest = 1e9;
    for (std::size_t i = 0; i < deformed.size() && !ok; ++i) {
      ok = casters[i].contains(d);
      nearest = std::min(nearest, geometry::closest_point_on_mesh(deformed[i], d).distance_mm);
    }
    if (!ok && nearest > tolerance) {
      ++outside;
      std::cout << "outside: " << d.transpose() << " by " << nearest << " mm\n";
      worst = std::max(worst, nearest);
    }
  }
  EXPECT_EQ(outside, 0) << "device points outside every vessel by more than Δd; worst " << worst << " mm";
  // Before deformation the same check fails: the example is a real test of the method.
  int outside_before = 0;
  std::vector<geometry::RayCaster> before;
  for (const auto& v : scene.vessels) before.emplace_back(v.mesh.mesh);
  for (const auto& d : example().device) {
    bool ok = false;
    for (std::size_t i = 0; i < before.size() && !ok; ++i)
      ok = before[i].contains(d) || geometry::closest_point_on_mesh(scene.vessels[i].mesh.mesh, d).distance_mm <= tolerance;
    outside_before += ok ? 0 : 1;
  }
  EXPECT_GT(outside_before, 10);
}

// CT coordinates put a patient anywhere, often a metre from the scanner's origin: the same
// scene and device moved there deform the same, moved. (Before the fix the ray
// caster's inside test failed in single precision there: 2.6 mm apart, other handles and
// erased vertices, 1.9 s instead of 40 ms.)
TEST(SceneDeformation, DeformsTheSameWhereverTheScannerPutThePatient) {
  const auto scene = sim::to_scene(example());
  const auto& device = example().device;
  const auto here = deform::deform_scene(scene, device);
  for (const Eigen::Vector3d& offset : {Eigen::Vector3d(-150.0, -150.0, -900.0), Eigen::Vector3d(320.0, 180.0, 1250.0)}) {
    auto moved = scene;
    for (auto& v : moved.vessels) {
      v.mesh.mesh.V.rowwise() += offset.transpose();
      for (auto& p : v.centerline) p += offset;
    }
    for (auto& l : moved.landmarks) l.position_lps += offset;
    geometry::Polyline moved_device = device;
    for (auto& p : moved_device) p += offset;
    const auto there = deform::deform_scene(moved, moved_device);
    ASSERT_EQ(there.vessels.size(), here.vessels.size());
    EXPECT_EQ(there.device_iliac, here.device_iliac);
    for (std::size_t i = 0; i < here.vessels.size(); ++i) {
      EXPECT_EQ(there.reports[i].control_points, here.reports[i].control_points) << here.reports[i].name;
      EXPECT_EQ(there.vessels[i].erased, here.vessels[i].erased) << here.reports[i].name;
      // Only double rounding of the larger coordinates may differ (measured: under 1e-4 mm).
      const double apart = ((there.vessels[i].mesh.V.rowwise() - offset.transpose()) - here.vessels[i].mesh.V)
                               .rowwise().norm().maxCoeff();
      EXPECT_LT(apart, 1e-3) << here.reports[i].name << " moved by " << offset.transpose();
    }
    for (std::size_t k = 0; k < here.landmarks.size(); ++k)
      EXPECT_LT((there.landmarks[k].position_lps - offset - here.landmarks[k].position_lps).norm(), 1e-3)
          << here.landmarks[k].label;
  }
}

// The device's order (tip first, by the format) does not change where it is: given from
// the access end it deforms the scene the same (before the fix its samples started at
// its first point and equal-depth handles were thinned in its order: 0.84 mm apart).
TEST(SceneDeformation, ADeviceGivenFromEitherEndDeformsTheSame) {
  const auto scene = sim::to_scene(example());
  const auto& device = example().device;
  const geometry::Polyline reversed(device.rbegin(), device.rend());
  const auto a = deform::deform_scene(scene, device), b = deform::deform_scene(scene, reversed);
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    EXPECT_EQ(a.reports[i].control_points, b.reports[i].control_points) << a.reports[i].name;
    EXPECT_LT((a.vessels[i].mesh.V - b.vessels[i].mesh.V).rowwise().norm().maxCoeff(), 1e-6) << a.reports[i].name;
  }
}

TEST(SceneDeformation, KeepsTopologyVertexOrderAndMovesLandmarksWithTheSurface) {
  const auto scene = sim::to_scene(example());
  const auto out = deform::deform_scene(scene, example().device);
  ASSERT_EQ(out.vessels.size(), scene.vessels.size());
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    EXPECT_EQ(out.vessels[i].mesh.V.rows(), scene.vessels[i].mesh.mesh.V.rows());
    EXPECT_TRUE(out.vessels[i].mesh.V.allFinite());
  }
  const auto& right = out.reports[2];
  EXPECT_EQ(right.name, "iliac_right");
  EXPECT_GT(right.control_points, 0);
  EXPECT_GT(right.bound_vertices, 0);
  EXPECT_TRUE(right.converged);
  EXPECT_GT(out.reports[0].erased_faces, 0);  // aortic stump below the bound iliac top
  ASSERT_EQ(out.landmarks.size(), example().landmarks.size());
  for (std::size_t k = 0; k < out.landmarks.size(); ++k) {
    EXPECT_EQ(out.landmarks[k].label, example().landmarks[k].label);
    // On the deformed surface of the vessel it follows.
    std::size_t v = 0;
    while (scene.vessels[v].name != out.landmark_vessel[k]) ++v;
    const geometry::TriangleMesh m{out.vessels[v].mesh.V, scene.vessels[v].mesh.mesh.F};
    EXPECT_LT(geometry::closest_point_on_mesh(m, out.landmarks[k].position_lps).distance_mm, 1e-6);
  }
  // The right internal iliac ostium moves with its deformed wall; the renals barely.
  const auto moved = [&](const std::string& label) {
    for (std::size_t k = 0; k < out.landmarks.size(); ++k)
      if (out.landmarks[k].label == label) return (out.landmarks[k].position_lps - example().landmarks[k].position_lps).norm();
    ADD_FAILURE() << label;
    return 0.0;
  };
  EXPECT_GT(moved("internal_iliac_right"), 1.0);
}

TEST(SceneDeformation, DeviceInsideTheLumenChangesNothing) {
  const auto scene = sim::to_scene(example());
  // The aortic centerline itself, as a device: inside everywhere.
  const auto& cl = example().vessel("aorta").centerline;
  std::vector<Eigen::Vector3d> device(cl.begin() + 10, cl.end() - 10);
  const auto out = deform::deform_scene(scene, device);
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    EXPECT_LT((out.vessels[i].mesh.V - scene.vessels[i].mesh.mesh.V).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_EQ(out.vessels[i].mesh.F.rows(), scene.vessels[i].mesh.mesh.F.rows());
  }
}

TEST(SceneDeformation, DeviceFarFromEveryVesselIsAClearError) {
  const auto scene = sim::to_scene(example());
  const std::vector<Eigen::Vector3d> device{{500, 500, 0}, {520, 500, 0}};
  try {
    deform::deform_scene(scene, device);
    FAIL() << "expected an evar::base::InputError";
  } catch (const base::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no part of the device lies in any vessel"), std::string::npos) << e.what();
  }
}

TEST(SceneDeformation, EmptyOrNonFiniteDeviceIsAClearError) {
  const auto scene = sim::to_scene(example());
  EXPECT_THROW(deform::deform_scene(scene, {}), base::InputError);
  EXPECT_THROW(deform::deform_scene(scene, {{0, 0, 0}, {NAN, 0, 0}}), base::InputError);
}

TEST(SceneDeformation, TetherKeepsLandmarksFarFromTheDeviceWhereRegistrationPutThem) {
  // The device leaves the aorta only near the bifurcation; the renal ostia, ~100 mm away,
  // should stay put (the paper: renal landmark positions are preserved). Without the
  // tether the handle cluster swings the whole aorta (kept as an option, asserted here so
  // the difference stays visible).
  const auto scene = sim::to_scene(example());
  const auto renal_shift = [&](double tether_mm) {
    deform::DeformOptions opt;
    opt.tether_length_mm = tether_mm;
    const auto out = deform::deform_scene(scene, example().device, opt);
    double worst = 0.0;
    for (std::size_t k = 0; k < out.landmarks.size(); ++k)
      if (out.landmarks[k].label.rfind("renal", 0) == 0)
        worst = std::max(worst, (out.landmarks[k].position_lps - example().landmarks[k].position_lps).norm());
    return worst;
  };
  const double tethered = renal_shift(50.0);
  EXPECT_LT(tethered, 1.0);
  EXPECT_GT(renal_shift(0.0), 3.0 * tethered);
}

TEST(SceneDeformation, KeepsTheOrderOfEveryFaceThatIsNotErased) {
  const auto scene = sim::to_scene(example());
  const auto out = deform::deform_scene(scene, example().device);
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    const auto& F_in = scene.vessels[i].mesh.mesh.F;
    const auto& F_out = out.vessels[i].mesh.F;
    const auto& erased = out.vessels[i].erased;
    Eigen::Index k = 0;
    for (Eigen::Index f = 0; f < F_in.rows(); ++f) {
      if (erased[F_in(f, 0)] || erased[F_in(f, 1)] || erased[F_in(f, 2)]) continue;
      ASSERT_LT(k, F_out.rows());
      ASSERT_EQ(F_out.row(k), F_in.row(f)) << scene.vessels[i].name << " face " << f;
      ++k;
    }
    EXPECT_EQ(k, F_out.rows());
  }
}

TEST(SceneDeformation, ErasesOnlyTheAorticStumpInsideTheDeviceIliac) {
  // The device runs up the right iliac (patient right = −x). The aortic wall below the
  // bound iliac top that lies inside the deformed right iliac goes; the left junction stays.
  const auto scene = sim::to_scene(example());
  const auto out = deform::deform_scene(scene, example().device);
  const auto& aorta = scene.vessels[0].mesh.mesh;
  int erased = 0;
  for (Eigen::Index k = 0; k < aorta.V.rows(); ++k) {
    if (!out.vessels[0].erased[static_cast<std::size_t>(k)]) continue;
    ++erased;
    EXPECT_LT(aorta.V(k, 0), 1.0) << "erased aortic vertex " << k << " on the left side";
  }
  EXPECT_GT(erased, 0);
}

// A landmark on the part of the aorta the carrier iliac replaces (an overlap between the
// aortic and iliac segmentations) must follow the iliac: the erased stump's vertices had
// nothing to hold them where the device bent the iliac (before the fix it stayed on them).
TEST(SceneDeformation, ALandmarkOnTheErasedStumpFollowsTheCarrierIliac) {
  auto scene = sim::to_scene(example());
  const auto first = deform::deform_scene(scene, example().device);
  const auto& aorta = scene.vessels[0].mesh.mesh;
  // The erased aortic vertex nearest the middle of the stump.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  int n = 0;
  for (Eigen::Index k = 0; k < aorta.V.rows(); ++k)
    if (first.vessels[0].erased[static_cast<std::size_t>(k)]) centre += aorta.V.row(k).transpose(), ++n;
  ASSERT_GT(n, 0);
  centre /= n;
  Eigen::Index pick = -1;
  for (Eigen::Index k = 0; k < aorta.V.rows(); ++k)
    if (first.vessels[0].erased[static_cast<std::size_t>(k)] &&
        (pick < 0 || (aorta.V.row(k).transpose() - centre).norm() < (aorta.V.row(pick).transpose() - centre).norm()))
      pick = k;
  const Eigen::Vector3d on_stump = aorta.V.row(pick).transpose();
  scene.landmarks.push_back({"on_stump", on_stump});
  const auto& iliac = scene.vessels[2];
  ASSERT_EQ(iliac.name, "iliac_right");
  const double from_iliac_mm = geometry::closest_point_on_mesh(iliac.mesh.mesh, on_stump).distance_mm;

  const auto out = deform::deform_scene(scene, example().device);
  ASSERT_EQ(out.landmarks.back().label, "on_stump");
  EXPECT_EQ(out.landmark_vessel.back(), "iliac_right");
  // It keeps its place relative to the iliac wall (a rigid-like neighbourhood: 0.2 mm),
  const geometry::TriangleMesh bent{out.vessels[2].mesh.V, iliac.mesh.mesh.F};
  EXPECT_NEAR(geometry::closest_point_on_mesh(bent, out.landmarks.back().position_lps).distance_mm, from_iliac_mm, 0.2);
  // and every other landmark still follows the vessel it sits on.
  for (std::size_t k = 0; k + 1 < out.landmarks.size(); ++k)
    EXPECT_EQ(out.landmark_vessel[k], first.landmark_vessel[k]) << out.landmarks[k].label;
}

// A device that runs inside the carrier iliac's lumen all the way gives it no handles; it
// still carries the device, so the aortic stump it replaces is erased as when it bends it
// (before the fix the erasure came and went with the handles, frame to frame).
TEST(SceneDeformation, TheStumpIsErasedAlsoWhenTheCarrierNeedsNoHandles) {
  const auto scene = sim::to_scene(example());
  const auto& aortic = example().vessel("aorta").centerline;
  const auto& iliac = example().vessel("iliac_right").centerline;
  std::vector<Eigen::Vector3d> device(aortic.begin() + 10, aortic.end());
  device.insert(device.end(), iliac.begin(), iliac.end() - 5);
  const auto out = deform::deform_scene(scene, device);
  EXPECT_EQ(out.device_iliac, "iliac_right");
  const std::size_t carrier = 2;
  ASSERT_EQ(out.reports[carrier].name, "iliac_right");
  EXPECT_EQ(out.reports[carrier].control_points, 0);
  EXPECT_EQ(out.reports[carrier].role, "carries the device");
  EXPECT_GT(out.reports[0].erased_vertices, 0);
  EXPECT_LT(out.vessels[0].mesh.F.rows(), scene.vessels[0].mesh.mesh.F.rows());
  // Nothing moved: no handle anywhere.
  for (std::size_t i = 0; i < scene.vessels.size(); ++i)
    EXPECT_LT((out.vessels[i].mesh.V - scene.vessels[i].mesh.mesh.V).cwiseAbs().maxCoeff(), 1e-9) << out.reports[i].name;
}

// Segmentations often leave a vessel's ends open. An iliac whose top cap is cut off has no
// inside for ray parity, yet the device in it must still count as in its lumen, not as
// pushing the aortic wall (before the fix the aorta got 5 handles instead of 1 and
// moved 3.8 mm instead of 1.5).
TEST(SceneDeformation, AnIliacWithAnOpenTopStillHoldsTheDeviceForTheAorta) {
  const auto closed = sim::to_scene(example());
  auto open = closed;
  auto& iliac = open.vessels[2];
  ASSERT_EQ(iliac.name, "iliac_right");
  // The top cap: the fan of faces around the vertex at the centerline's first point.
  Eigen::Index tip = 0;
  (iliac.mesh.mesh.V.rowwise() - iliac.centerline.front().transpose()).rowwise().norm().minCoeff(&tip);
  std::vector<Eigen::RowVector3i> kept;
  for (Eigen::Index f = 0; f < iliac.mesh.mesh.F.rows(); ++f)
    if ((iliac.mesh.mesh.F.row(f).array() != static_cast<int>(tip)).all()) kept.push_back(iliac.mesh.mesh.F.row(f));
  ASSERT_LT(kept.size(), static_cast<std::size_t>(iliac.mesh.mesh.F.rows()));
  iliac.mesh.mesh.F.resize(static_cast<Eigen::Index>(kept.size()), 3);
  for (std::size_t f = 0; f < kept.size(); ++f) iliac.mesh.mesh.F.row(static_cast<Eigen::Index>(f)) = kept[f];
  ASSERT_FALSE(geometry::is_closed(iliac.mesh.mesh));

  const auto a = deform::deform_scene(closed, example().device);
  const auto b = deform::deform_scene(open, example().device);
  // The radius profile is not the faceted wall: a handle more or less where the device
  // grazes the junction, not the 4 extra ones of an open mesh without a lumen.
  EXPECT_LE(b.reports[0].control_points, a.reports[0].control_points + 1);
  EXPECT_NEAR(b.reports[0].max_displacement_mm, a.reports[0].max_displacement_mm, 0.25);
  EXPECT_NEAR(b.reports[1].max_displacement_mm, a.reports[1].max_displacement_mm, 0.25);  // the other iliac follows it
}

// An iliac that begins well away from the aorta (a gap between the meshes, another frame)
// would have its top bound to an aortic wall it never met: refused by name.
TEST(SceneDeformation, AnIliacThatBeginsOutsideTheAortaIsRefusedByName) {
  auto scene = sim::to_scene(example());
  auto& iliac = scene.vessels[2];
  const Eigen::Vector3d away(-40.0, 0.0, -30.0);
  iliac.mesh.mesh.V.rowwise() += away.transpose();
  for (auto& p : iliac.centerline) p += away;
  try {
    (void)deform::SceneDeformer(scene);
    ADD_FAILURE() << "an iliac 40 mm from the aorta was bound to it";
  } catch (const base::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("iliac 'iliac_right' begins"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("outside the aorta"), std::string::npos) << e.what();
  }
}

TEST(SceneDeformation, FindsTheIliacCarryingTheDeviceFromTheGeometry) {
  // Nominal anatomy (no seeded variation: the iliacs are mirror images) with the device
  // mirrored left-right, so it runs up the left iliac instead of the right.
  sim::ExampleSceneParams p;
  p.variation = 0.0;
  auto ex = sim::make_example_scene(p);
  for (auto& d : ex.device) d.x() *= -1.0;
  const auto out = deform::deform_scene(sim::to_scene(ex), ex.device);
  EXPECT_EQ(out.device_iliac, "iliac_left");
  EXPECT_GT(out.reports[1].control_points, 0);
  EXPECT_EQ(out.reports[2].control_points, 0);
  // And it is not solved: in this nominal anatomy the aorta does not move at its junction.
  EXPECT_EQ(out.reports[2].role, "unchanged");
}

TEST(SceneDeformation, ContralateralIliacBendsAfterTheJunctionAndKeepsItsDistalEnd) {
  const auto scene = sim::to_scene(example());
  const auto out = deform::deform_scene(scene, example().device);
  const auto& r = out.reports[1];
  EXPECT_EQ(r.role, "follows the aorta");
  EXPECT_EQ(r.control_points, 0);  // nothing from the device: only the junction moves it
  EXPECT_GT(r.iterations, 0);
  const auto& iliac = scene.vessels[1];
  const auto& V0 = iliac.mesh.mesh.V;
  const auto& V = out.vessels[1].mesh.V;
  const auto& aorta0 = scene.vessels[0].mesh.mesh.V;
  const auto& aorta = out.vessels[0].mesh.V;
  const geometry::PolylineProjector onto(iliac.centerline);
  const double length = geometry::arc_lengths(iliac.centerline).back();
  double junction_mm = 0.0, distal_mm = 0.0, gap_mm = 0.0;
  int bound = 0;
  for (Eigen::Index k = 0; k < V0.rows(); ++k) {
    const Eigen::Vector3d p = V0.row(k).transpose();
    const double s = onto.project(p).arc_length_mm;
    const double moved = (V.row(k) - V0.row(k)).norm();
    if (s <= deform::DeformOptions{}.bind_length_mm) {
      // Bound: moved exactly as the aortic surface at its closest point, so the junction
      // stays closed.
      const auto at = geometry::closest_point_on_mesh(scene.vessels[0].mesh.mesh, p);
      Eigen::Vector3d shift = Eigen::Vector3d::Zero();
      for (int j = 0; j < 3; ++j) {
        const int a = scene.vessels[0].mesh.mesh.F(at.face, j);
        shift += at.barycentric[j] * (aorta.row(a) - aorta0.row(a)).transpose();
      }
      EXPECT_LT((V.row(k) - V0.row(k) - shift.transpose()).norm(), 1e-9) << "vertex " << k;
      junction_mm = std::max(junction_mm, moved);
      gap_mm = std::max(gap_mm, at.distance_mm);
      ++bound;
    }
    if (s >= length - 10.0) distal_mm = std::max(distal_mm, moved);
  }
  EXPECT_EQ(bound, r.bound_vertices);
  // The report says how far the bound ring lies from the aortic wall it follows.
  EXPECT_NEAR(r.junction_gap_mm, gap_mm, 1e-9);
  ASSERT_GT(junction_mm, 0.5) << "the example's aorta should move the junction";
  // The distal end (its last 10 mm) stays near its registered pose: well under the
  // junction's move (a rigid follow would move it as far).
  EXPECT_LT(distal_mm, 0.25 * junction_mm);
  // And the iliac bends rather than stretches: edges keep their length within 5 %.
  EXPECT_LT(worst_edge_strain(iliac.mesh.mesh.F, V0, V), 0.05);
}

// Where the device passes from the aorta into the iliac it is outside the aortic wall but
// inside the iliac's lumen: it pushes neither. Handles there would drag the aortic wall
// into the iliac's opening (edges stretched by half their length on the example).
TEST(SceneDeformation, TheDevicePassingIntoTheIliacDoesNotPullTheAorticWall) {
  const auto scene = sim::to_scene(example());
  const auto out = deform::deform_scene(scene, example().device);
  EXPECT_LT(worst_edge_strain(scene.vessels[0].mesh.mesh.F, scene.vessels[0].mesh.mesh.V, out.vessels[0].mesh.V), 0.10);
  // And no aortic handle sits where the device is inside an iliac.
  std::vector<geometry::RayCaster> iliacs;
  for (std::size_t i = 1; i < scene.vessels.size(); ++i) iliacs.emplace_back(scene.vessels[i].mesh.mesh);
  const auto& m = scene.vessels[0];
  const geometry::RayCaster aorta(m.mesh.mesh);
  deform::SkeletonOptions so;
  const auto radius = deform::radius_profile(deform::build_skeleton(aorta, m.centerline, so));
  deform::ControlPointOptions co;
  co.device_thickness_mm = scene.device_thickness_mm;
  const auto in_iliac = [&](const Eigen::Vector3d& p) {
    return std::any_of(iliacs.begin(), iliacs.end(), [&](const geometry::RayCaster& c) { return c.contains(p); });
  };
  const auto all = deform::select_control_points(m.mesh.mesh, aorta, m.centerline, radius, example().device, co);
  const auto kept = deform::select_control_points(m.mesh.mesh, aorta, m.centerline, radius, example().device, co, in_iliac);
  EXPECT_LT(kept.size(), all.size()) << "the example's device should leave the aorta through its wall into the iliac";
  for (const auto& h : kept) EXPECT_FALSE(in_iliac(h.device_point));
}

TEST(SceneDeformation, RefusesAReversedIliacCenterline) {
  auto scene = sim::to_scene(example());
  std::reverse(scene.vessels[2].centerline.begin(), scene.vessels[2].centerline.end());
  try {
    deform::SceneDeformer deformer(scene);
    FAIL() << "expected an evar::base::InputError";
  } catch (const base::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("iliac_right.centerline.mrk.json"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("runs toward the aorta"), std::string::npos) << e.what();
  }
}

// A mesh in metres (a unit slip on export) lies nowhere near its centerline in mm: refused,
// and the message says where each lies and what to check (before the fix it said only
// that no slicing plane hit the wall).
TEST(SceneDeformation, AMeshInOtherUnitsIsRefusedSayingWhereMeshAndCenterlineLie) {
  auto scene = sim::to_scene(example());
  scene.vessels[0].mesh.mesh.V /= 1000.0;
  try {
    deform::SceneDeformer deformer(scene);
    FAIL() << "expected an evar::base::InputError";
  } catch (const base::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("does not run inside its mesh"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("The mesh spans"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("millimetres in patient LPS"), std::string::npos) << e.what();
  }
}

TEST(SceneDeformation, RefusesALandmarkFarFromEveryVessel) {
  auto scene = sim::to_scene(example());
  scene.landmarks.push_back({"stray", {300.0, 0.0, 0.0}});
  try {
    deform::SceneDeformer deformer(scene);
    FAIL() << "expected an evar::base::InputError";
  } catch (const base::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("landmark 'stray'"), std::string::npos) << e.what();
  }
}

TEST(SceneDeformation, RefusesADeviceWithAStrayFarPoint) {
  const auto scene = sim::to_scene(example());
  auto device = example().device;
  device.insert(device.begin() + 10, Eigen::Vector3d(9e4, 0.0, 0.0));
  try {
    deform::deform_scene(scene, device);
    FAIL() << "expected an evar::base::InputError";
  } catch (const base::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("stray control point"), std::string::npos) << e.what();
  }
}

TEST(SceneDeformation, WarmStartFromThePreviousFrameReachesTheSameShape) {
  const auto scene = sim::to_scene(example());
  deform::DeformOptions tight;
  tight.arap.tolerance_mm = 1e-4;  // both runs close to the one fixed point
  const deform::SceneDeformer deformer(scene, tight);
  // Frame 0, then the device 0.5 mm further to the patient's left (a breath, a push).
  const auto frame0 = deformer.deform(example().device);
  geometry::Polyline moved = example().device;
  for (auto& p : moved) p.x() += 0.5;
  const auto cold = deformer.deform(moved);
  const auto warm = deformer.deform(moved, &frame0);
  int cold_iterations = 0, warm_iterations = 0;
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    cold_iterations += cold.reports[i].iterations;
    warm_iterations += warm.reports[i].iterations;
    ASSERT_EQ(warm.reports[i].control_points, cold.reports[i].control_points) << scene.vessels[i].name;
    // 1e-4 mm updates leave both within about 0.005 mm of the fixed point (docs/BENCHMARKS.md).
    EXPECT_LT((warm.vessels[i].mesh.V - cold.vessels[i].mesh.V).rowwise().norm().maxCoeff(), 0.02)
        << scene.vessels[i].name;
  }
  // About as many: with the iliac's sections paired with the device (ordered_pairing.hpp)
  // the handles pin it, the Laplacian-editing guess of a cold start is already close, and
  // the count is set by the convergence rate (on the example 15 cold and 16 warm at this
  // tolerance, 7 and 7 at the default, for shifts of 0.5 and 2 mm alike).
  EXPECT_LE(warm_iterations, cold_iterations + 1);
  deform::SceneDeformation other = frame0;
  other.vessels.pop_back();
  EXPECT_THROW(deformer.deform(moved, &other), std::invalid_argument);
}

// A hundredth of a millimetre of device moves no vertex by a millimetre: a ray from the
// last section to a device point level with the iliac's end runs in its cap's plane and
// hit the rim or not by rounding, and its handle swung the free end by 4 mm; no handle
// lies within a sample step of either end. (The thinning of the handles still jumps by a
// few tenths where the order of equal depths changes.)
// (The example as `evarnode example` writes it: its float meshes put the wire's end level
// with the iliac's.)
TEST(SceneDeformation, AHundredthOfAMillimetreOfDeviceMovesTheCarrierByLessThanAMillimetre) {
  const test::TempDir dir;
  sim::write_example_scene(example(), dir.path);
  const geometry::Scene scene = geometry::load_scene(dir.path / "scene.json");
  geometry::Polyline device;
  for (const auto& p : geometry::read_curve(dir.path / "device.mrk.json").points) device.push_back(p.position_lps);
  const deform::SceneDeformer deformer(scene, {});
  const auto before = deformer.deform(device);
  geometry::Polyline nudged = device;
  for (auto& p : nudged) p.x() += 0.01;
  const auto after = deformer.deform(nudged);
  for (std::size_t i = 0; i < scene.vessels.size(); ++i)
    EXPECT_LT((after.vessels[i].mesh.V - before.vessels[i].mesh.V).rowwise().norm().maxCoeff(), 1.0)
        << scene.vessels[i].name;
}

// The iliacs solved at once give what one after the other gives, bit for bit: each reads
// the deformed aorta only, and only the carrier writes the aorta's erasure.
TEST(SceneDeformation, TheIliacsSolvedAtOnceGiveExactlyWhatOneAfterTheOtherGives) {
  const auto scene = sim::to_scene(example());
  deform::DeformOptions at_once, in_turn;
  at_once.parallel_iliacs = true;
  in_turn.parallel_iliacs = false;
  const auto a = deform::SceneDeformer(scene, at_once).deform(example().device);
  const auto b = deform::SceneDeformer(scene, in_turn).deform(example().device);
  ASSERT_EQ(a.vessels.size(), b.vessels.size());
  int moved_iliacs = 0;
  for (std::size_t i = 0; i < a.vessels.size(); ++i) {
    EXPECT_EQ(a.vessels[i].mesh.V, b.vessels[i].mesh.V) << a.reports[i].name;
    EXPECT_EQ(a.vessels[i].mesh.F, b.vessels[i].mesh.F) << a.reports[i].name;
    EXPECT_EQ(a.vessels[i].erased, b.vessels[i].erased) << a.reports[i].name;
    EXPECT_EQ(a.reports[i].iterations, b.reports[i].iterations) << a.reports[i].name;
    if (a.reports[i].kind == "iliac" && a.reports[i].iterations > 0) ++moved_iliacs;
  }
  EXPECT_EQ(moved_iliacs, 2);  // both iliacs were solved: the carrier and the one that follows
  for (std::size_t k = 0; k < a.landmarks.size(); ++k)
    EXPECT_EQ(a.landmarks[k].position_lps, b.landmarks[k].position_lps) << a.landmarks[k].label;
}
