// Scenes from segmentation-like surfaces the project makes itself (sim's segmentation
// phantom: a label volume through VTK's marching cubes, staircase and slivers included),
// in LPS, RAS and image axes, without centerlines: every step checked against the
// phantom's truth, and the image-axes surface refused until its axes are said.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <memory>

#include "evar/base/input_error.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/prepare/scene_preparation.hpp"
#include "evar/prepare/surface_centerlines.hpp"
#include "evar/sim/segmentation_phantom.hpp"
#include "support/error_message.hpp"
#include "support/temp_dir.hpp"
#include "support/untagged_stl.hpp"

using namespace evar;

namespace {

// Distance from `p` to the nearest of `paths`, each run on 5 mm straight past both ends
// (the phantom's flat caps lie up to a voxel past its axes' ends).
double distance_to(const std::vector<geometry::Polyline>& paths, const Eigen::Vector3d& p) {
  double d = INFINITY;
  for (auto path : paths) {
    const Eigen::Vector3d before = path[0] + 5.0 * (path[0] - path[1]).normalized();
    const Eigen::Vector3d after = path.back() + 5.0 * (path.back() - path[path.size() - 2]).normalized();
    path.insert(path.begin(), before);
    path.push_back(after);
    d = std::min(d, geometry::project_onto(path, p).distance_mm);
  }
  return d;
}

// The vertices on the mesh's open rims (edges of one face).
std::vector<Eigen::Vector3d> rim_vertices(const geometry::TriangleMesh& m) {
  std::map<std::pair<int, int>, int> edges;
  for (Eigen::Index f = 0; f < m.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = m.F(f, k), b = m.F(f, (k + 1) % 3);
      ++edges[{std::min(a, b), std::max(a, b)}];
    }
  std::map<int, Eigen::Vector3d> rim;
  for (const auto& [e, n] : edges)
    if (n == 1) rim[e.first] = m.V.row(e.first).transpose(), rim[e.second] = m.V.row(e.second).transpose();
  std::vector<Eigen::Vector3d> out;
  for (const auto& [v, p] : rim) out.push_back(p);
  return out;
}

// The largest distance of `points` from their best-fitting plane.
double off_plane_mm(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p / static_cast<double>(points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& p : points) scatter += (p - mean) * (p - mean).transpose();
  const Eigen::Vector3d normal = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvectors().col(0);
  double worst = 0.0;
  for (const auto& p : points) worst = std::max(worst, std::abs((p - mean).dot(normal)));
  return worst;
}

// Why prepare_scene refuses `phantom`'s surface written as an untagged STL, read as LPS.
std::string refusal_of(const sim::SegmentationPhantom& phantom, const std::filesystem::path& path) {
  test::write_untagged_stl(path, phantom.surface);
  return test::error_message<base::InputError>([&] { prepare::prepare_scene({path, {}, {}, ""}); });
}

// Near the bifurcation (within the aortic bottom's reach) or a stub's ostium.
bool near_a_junction(const sim::SegmentationPhantom& phantom, const Eigen::Vector3d& p) {
  if ((p - phantom.bifurcation).norm() < 25.0) return true;
  for (const auto& o : phantom.ostia)
    if ((p - o.position_lps).norm() < 8.0) return true;
  return false;
}

// The smallest angle of each face, in degrees.
std::vector<double> smallest_angles_deg(const geometry::TriangleMesh& m) {
  std::vector<double> out;
  for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
    double smallest = 180.0;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d a = m.V.row(m.F(f, k)).transpose(), b = m.V.row(m.F(f, (k + 1) % 3)).transpose(),
                            c = m.V.row(m.F(f, (k + 2) % 3)).transpose();
      const double cosine = (b - a).normalized().dot((c - a).normalized());
      smallest = std::min(smallest, std::acos(std::clamp(cosine, -1.0, 1.0)) * 180.0 / M_PI);
    }
    out.push_back(smallest);
  }
  return out;
}

}  // namespace

// What the phantom is: one closed surface, the voxel spacing's edges, and the slivers and
// staircase an unsmoothed segmentation export has.
TEST(SegmentationPhantom, IsOneClosedSurfaceWithTheSliversOfAnUnsmoothedExport) {
  const auto phantom = sim::make_segmentation_phantom();
  ASSERT_NO_THROW(geometry::validate_mesh(phantom.surface, "phantom"));
  EXPECT_TRUE(geometry::is_closed(phantom.surface));
  const double edge = geometry::median_edge_length(phantom.surface);
  EXPECT_GT(edge, 0.3);
  EXPECT_LT(edge, 1.5);
  const auto angles = smallest_angles_deg(phantom.surface);
  const auto slivers = std::count_if(angles.begin(), angles.end(), [](double a) { return a < 5.0; });
  EXPECT_GT(slivers, 20) << "an intensity threshold's marching cubes leaves slivers";
  EXPECT_EQ(phantom.ostia.size(), 4u);
  EXPECT_EQ(phantom.paths.size(), 6u);
}

// The surface alone, in each frame a segmentation tool writes and in several formats: the
// computed centerlines follow the truth, the pieces are the whole surface, the iliacs are
// told apart, and the four side-branch stubs become the four ostia with their right names.
TEST(SceneFromSegmentation, TheSurfaceAloneInEachFrameMakesTheSceneOfItsTruth) {
  const test::TempDir dir;
  struct Case {
    sim::PhantomFrame frame;
    std::string file;
    bool tagged;       // written by evarnode's writer, declaring its space; else an untagged STL
    geometry::MeshSpace tag;
    std::string axes;  // --axes
  };
  const std::vector<Case> cases{
      {sim::PhantomFrame::Lps, "lps.stl", true, geometry::MeshSpace::Lps, ""},
      {sim::PhantomFrame::Lps, "ras-tagged.vtk", true, geometry::MeshSpace::Ras, ""},  // RAS coordinates, SPACE=RAS
      {sim::PhantomFrame::Ras, "ras.stl", false, {}, "RAS"},
      {sim::PhantomFrame::Image, "image.stl", false, {}, "LIP"}};
  for (const auto& c : cases) {
    SCOPED_TRACE(c.file);
    const auto phantom = sim::make_segmentation_phantom({.frame = c.frame});
    const auto path = dir.path / c.file;
    if (c.tagged)
      geometry::write_mesh(path, phantom.surface, geometry::format_for_extension(path), c.tag);
    else
      test::write_untagged_stl(path, phantom.surface);
    const auto scene = prepare::prepare_scene({path, {}, {}, c.axes});

    ASSERT_EQ(scene.vessels.size(), 3u);
    EXPECT_EQ(scene.axes, c.tag == geometry::MeshSpace::Ras ? "RAS" : phantom.axes);
    // Every centerline point on the truth's axes (the skeleton of a voxel staircase of
    // 0.8 x 0.8 x 1.5 mm: within a voxel's diagonal, 1.9 mm, and mostly well within), the
    // aorta from its inlet down, each iliac to its outlet; but for the junctions, where the
    // phantom's axes (a branch's start inside its parent) are not its medial axis.
    std::vector<double> off;
    std::string worst;
    for (const auto& v : scene.vessels)
      for (std::size_t i = 0; i < v.centerline.size(); ++i) {
        const Eigen::Vector3d& p = v.centerline[i];
        if (near_a_junction(phantom, p)) continue;
        off.push_back(distance_to(phantom.paths, p));
        if (off.back() >= *std::max_element(off.begin(), off.end()))
          worst = v.name + " point " + std::to_string(i) + " of " + std::to_string(v.centerline.size());
      }
    std::sort(off.begin(), off.end());
    EXPECT_LT(off[off.size() / 2], 0.6);
    EXPECT_LT(off.back(), 1.9) << worst;
    const auto& aorta = scene.vessels[0].centerline;
    EXPECT_NEAR(aorta.front().z(), 130.0, 1.5);  // the inlet's flat cap: at 130 mm, within a voxel
    EXPECT_LT(scene.vessels[1].centerline.back().x(), -25.0);  // iliac_right to the patient's right
    EXPECT_GT(scene.vessels[2].centerline.back().x(), 25.0);
    EXPECT_LT(scene.vessels[1].centerline.back().z(), -85.0);  // down to the outlet
    // The pieces are the surface, cut where the iliacs leave the aorta: at least its faces
    // (more where the cuts split them), and each iliac's top a plane section.
    Eigen::Index faces = 0;
    for (const auto& v : scene.vessels) faces += v.mesh.F.rows();
    EXPECT_GE(faces, phantom.surface.F.rows());
    for (const std::size_t i : {1u, 2u}) {
      const auto rim = rim_vertices(scene.vessels[i].mesh);
      ASSERT_GT(rim.size(), 10u) << scene.vessels[i].name;
      EXPECT_LT(off_plane_mm(rim), 1e-3) << scene.vessels[i].name << "'s top is not a plane section";
    }
    // The ostia: the stubs', named as they branch and point, each on the wall within a
    // stub's radius and a voxel of the truth.
    std::map<std::string, Eigen::Vector3d> found;
    for (const auto& lm : scene.landmarks) found[lm.label] = lm.position_lps;
    ASSERT_EQ(found.size(), 4u);
    for (const auto& truth : phantom.ostia) {
      ASSERT_TRUE(found.count(truth.label)) << truth.label;
      EXPECT_LT((found[truth.label] - truth.position_lps).norm(), 3.0 + 1.5) << truth.label;
    }
  }
}

// In its image's axes (LIP: the aorta runs to the file's -y) and read as LPS, the surface is
// refused, saying the axis and the option; nothing is rotated.
TEST(SceneFromSegmentation, ASurfaceInImageAxesIsRefusedUntilItsAxesAreSaid) {
  const test::TempDir dir;
  const std::string message = refusal_of(
      sim::make_segmentation_phantom({.frame = sim::PhantomFrame::Image, .side_branches = false}), dir.path / "image.stl");
  EXPECT_NE(message.find("along the file's -y axis"), std::string::npos) << message;
  EXPECT_NE(message.find("--axes"), std::string::npos) << message;
  EXPECT_NE(message.find("Nothing is rotated without being asked"), std::string::npos) << message;
}

// Coarser voxels than a CT's usual, and isotropic ones: the same seven skeleton ends
// (inlet, two outlets, four stubs), so the same four ostia. At 0.8 mm isotropic the flow
// pulls the aorta's end back to 9 mm above the renal branch point, inside that junction's
// lumen; it is still the aorta's end (no other branch leaves that way), not a spur.
TEST(SceneFromSegmentation, OtherVoxelSpacingsGiveTheSameFourOstia) {
  const test::TempDir dir;
  for (const Eigen::Vector3d& spacing :
       {Eigen::Vector3d(1.0, 1.0, 2.0), Eigen::Vector3d(1.2, 1.2, 2.5), Eigen::Vector3d(0.8, 0.8, 0.8)}) {
    SCOPED_TRACE(spacing.transpose());
    const auto phantom = sim::make_segmentation_phantom({.spacing_mm = spacing});
    const auto path = dir.path / "surface.stl";
    test::write_untagged_stl(path, phantom.surface);
    const auto scene = prepare::prepare_scene({path, {}, {}, ""});
    std::map<std::string, Eigen::Vector3d> found;
    for (const auto& lm : scene.landmarks) found[lm.label] = lm.position_lps;
    ASSERT_EQ(found.size(), 4u);
    for (const auto& truth : phantom.ostia) {
      ASSERT_TRUE(found.count(truth.label)) << truth.label;
      EXPECT_LT((found[truth.label] - truth.position_lps).norm(), 3.0 + spacing.maxCoeff()) << truth.label;
    }
  }
}

// Cropped 7 mm above the renal arteries, the aorta leaves its skeleton no end of its own (it
// collapses into the renal branch point): no end is clearly wider than the iliacs', and the
// surface is refused saying why and what to do, not read with an iliac as the inlet.
TEST(SceneFromSegmentation, AnAortaCroppedJustAboveItsRenalArteriesIsRefusedWithTheFix) {
  const test::TempDir dir;
  const std::string message =
      refusal_of(sim::make_segmentation_phantom({.lowest_z_mm = -55.0, .highest_z_mm = 105.0}), dir.path / "cropped.stl");
  EXPECT_NE(message.find("no end clearly wider than the others to be the aortic inlet"), std::string::npos) << message;
  EXPECT_NE(message.find("segment the aorta on for at least its diameter above its highest branch"), std::string::npos) << message;
  EXPECT_NE(message.find("--centerlines"), std::string::npos) << message;
}

// A stray island beside the bifurcation (a second copy of it, 200 mm away): its skeleton is in
// two pieces, and the surface is refused saying so and what to do.
TEST(SceneFromSegmentation, ASurfaceInSeveralPiecesIsRefusedWithTheFix) {
  const test::TempDir dir;
  auto phantom = sim::make_segmentation_phantom({.spacing_mm = {1.2, 1.2, 2.5}, .side_branches = false});
  geometry::TriangleMesh& m = phantom.surface;
  const Eigen::Index nv = m.V.rows(), nf = m.F.rows();
  m.V.conservativeResize(2 * nv, 3);
  m.F.conservativeResize(2 * nf, 3);
  m.V.bottomRows(nv) = m.V.topRows(nv).rowwise() + Eigen::RowVector3d(200.0, 0.0, 0.0);
  m.F.bottomRows(nf) = m.F.topRows(nf).array() + static_cast<int>(nv);
  const std::string message = refusal_of(phantom, dir.path / "two.stl");
  EXPECT_NE(message.find("the surface is in 2 separate pieces"), std::string::npos) << message;
  EXPECT_NE(message.find("Islands"), std::string::npos) << message;
}

// The skeleton does not depend on where the heap put things (CGAL orders the flow's edge
// collapses by address unless told otherwise): the same surface, skeletonised three times in
// one process with the heap in another state each time, gives the same centerlines to the
// last bit, so a scene, and any failure met on it, can be made again.
TEST(SceneFromSegmentation, TheSameSurfaceGivesTheSameCenterlinesEveryTime) {
  const auto phantom = sim::make_segmentation_phantom({.spacing_mm = {1.2, 1.2, 2.5}, .side_branches = false});
  const geometry::RayCaster walls(phantom.surface);
  const auto first = prepare::centerlines_from_surface(phantom.surface, walls, "phantom");
  ASSERT_EQ(first.paths.size(), 2u);
  std::vector<std::unique_ptr<char[]>> clutter;
  for (int run = 1; run <= 2; ++run) {
    SCOPED_TRACE("run " + std::to_string(run));
    for (std::size_t k = 0; k < 2000; ++k) clutter.push_back(std::make_unique<char[]>(24 + 40 * (k % 7) * run));
    for (std::size_t k = 0; k < clutter.size(); k += 3) clutter[k].reset();
    const auto again = prepare::centerlines_from_surface(phantom.surface, walls, "phantom");
    EXPECT_EQ(again.skeleton_points, first.skeleton_points);
    ASSERT_EQ(again.paths.size(), first.paths.size());
    for (std::size_t i = 0; i < first.paths.size(); ++i) {
      ASSERT_EQ(again.paths[i].points.size(), first.paths[i].points.size()) << "path " << i;
      for (std::size_t j = 0; j < first.paths[i].points.size(); ++j)
        ASSERT_EQ(again.paths[i].points[j], first.paths[i].points[j]) << "path " << i << " point " << j;
    }
  }
}
