// `evarnode scene` on real third-party data (VMTK's aorto-iliac segmentation) and on the
// simulator's segmentation phantom: every form they come in is made into a scene that
// `deform` takes, and a wire pushed out of the right iliac ends inside the deformed vessel,
// with no face turned over.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "evar/geometry/centerline_file.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/scene.hpp"
#include "support/cli_fixture.hpp"
#include "support/shared_data.hpp"
#include "evar/sim/segmentation_phantom.hpp"
#include "support/temp_dir.hpp"
#include "support/untagged_stl.hpp"

namespace fs = std::filesystem;
using evar::test::evarnode;

namespace {

nlohmann::json read_json(const fs::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in);
}

// The aortic centerline down to where the iliac paths part, then the right iliac's, bulged
// 8 mm (about two of its radii) to the patient's right in its middle: a stiff wire
// straightening the iliac. Tip first (in the aorta).
evar::geometry::Polyline pushed_wire(const evar::geometry::Scene& scene) {
  const auto& aorta = scene.vessels[0].centerline;
  const auto& right = scene.vessels[1].centerline;
  const auto fork = evar::geometry::project_onto(aorta, right.front());
  evar::geometry::Polyline wire;
  const auto arc = evar::geometry::arc_lengths(aorta);
  for (std::size_t i = 0; i < aorta.size() && arc[i] < fork.arc_length_mm - 5.0; ++i) wire.push_back(aorta[i]);
  const auto r_arc = evar::geometry::arc_lengths(right);
  for (std::size_t i = 0; i < right.size(); ++i)
    wire.push_back(right[i] + Eigen::Vector3d(-8.0 * std::sin(M_PI * r_arc[i] / r_arc.back()), 0, 0));
  return wire;
}

// Faces whose normal turned by more than 90° in the deformation.
int faces_turned_over(const evar::geometry::TriangleMesh& before, const evar::geometry::TriangleMesh& after) {
  int turned = 0;
  for (Eigen::Index f = 0; f < after.F.rows(); ++f) {
    const auto n = [&](const evar::geometry::TriangleMesh& m) {
      const Eigen::Vector3d a = m.V.row(after.F(f, 0)).transpose(), b = m.V.row(after.F(f, 1)).transpose(),
                            c = m.V.row(after.F(f, 2)).transpose();
      return Eigen::Vector3d((b - a).cross(c - a));
    };
    turned += n(before).dot(n(after)) < 0.0;
  }
  return turned;
}

// deform with the pushed wire: contained after (--strict exits 0), no face turned over.
void deform_with_pushed_wire(const evar::geometry::Scene& scene, const fs::path& out) {
  auto wire = pushed_wire(scene);
  evar::geometry::Markup device{"Curve", "wire", {}};
  for (std::size_t i = 0; i < wire.size(); ++i) device.points.push_back({"w-" + std::to_string(i + 1), wire[i]});
  const auto device_file = out / "wire.mrk.json";
  evar::geometry::write_markups(device_file, {device});
  const auto deformed = out / "deformed";
  const auto run = evarnode({"deform", "--scene", (out / "scene.json").string(), "--device", device_file.string(), "--out",
                             deformed.string(), "--strict", "--no-preview"});
  ASSERT_EQ(run.code, 0) << run.err;
  const auto result = read_json(deformed / "report.json");
  EXPECT_EQ(result["device_iliac"], "iliac_right");
  EXPECT_LT(result["device_outside_max_depth_mm"].get<double>(), 0.5);
  double moved = 0.0;
  for (const auto& v : result["vessels"]) {
    // Every proxy read from the file `scene` kept, none made anew.
    if (v["proxy_vertices"].get<int>() > 0) {
      EXPECT_NE(v["proxy_file"], "") << v["name"];
      EXPECT_EQ(v["proxy_file_unused"], "") << v["name"];
    }
  }
  for (const auto& v : result["vessels"])
    if (v["name"] == "iliac_right") {
      moved = v["max_displacement_mm"].get<double>();
      EXPECT_GT(v["control_points"].get<int>(), 0);
    }
  EXPECT_GT(moved, 2.0);  // the wire bent it
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    const auto after = evar::geometry::read_mesh(deformed / scene.vessels[i].mesh_path.filename()).mesh;
    EXPECT_EQ(faces_turned_over(scene.vessels[i].mesh.mesh, after), 0) << scene.vessels[i].name;
  }
}

}  // namespace

// Each form the data comes in: the surface as .vtp and as .stl, VMTK's branch-split surface
// (its pieces stored apart), the centerline paths, VMTK's branch pieces, and no centerlines
// at all (computed from the surface).
TEST(CliScene, EveryFormOfVmtksDataMakesASceneDeformTakesAndThePushedWireEndsInside) {
  EVAR_VMTK_DATA_OR_SKIP(data);
  const evar::test::TempDir dir;
  const std::vector<std::pair<std::string, std::string>> forms{
      {"aorta-surface.vtp", "aorta-centerline.vtp"},
      {"aorta-surface.stl", "aorta-centerline.vtp"},
      {"aorta-surface.vtp", "aorta-centerline-branches.vtp"},
      {"aorta-surface-branch-split.vtp", "aorta-centerline-branches.vtp"},
      {"aorta-surface.vtp", ""},
      {"aorta-surface.stl", ""},
      {"aorta-surface-branch-split.vtp", ""}};
  int k = 0;
  for (const auto& [surface, centerlines] : forms) {
    SCOPED_TRACE(surface + " + " + (centerlines.empty() ? "no centerlines" : centerlines));
    const auto out = dir.path / ("scene" + std::to_string(++k));
    // The data is in the image's axes, its aorta running to +y: said with --axes.
    std::vector<std::string> args{"scene", "--surface", (data / surface).string(), "--axes", "RSP", "--out", out.string()};
    if (!centerlines.empty()) args.insert(args.end(), {"--centerlines", (data / centerlines).string()});
    const auto made = evarnode(args);
    ASSERT_EQ(made.code, 0) << made.err;
    if (centerlines.empty()) {
      EXPECT_NE(made.err.find("no centerlines given: computed from the surface's mean-curvature-flow skeleton"),
                std::string::npos) << made.err;
    }
    for (const char* f : {"scene.json", "scene_report.json", "scene.png", "aorta.centerline.mrk.json",
                          "iliac_right.centerline.mrk.json", "iliac_left.centerline.mrk.json"})
      EXPECT_TRUE(fs::exists(out / f)) << f;
    const auto report = read_json(out / "scene_report.json");
    EXPECT_EQ(report["axes"], "RSP");
    ASSERT_EQ(report["vessels"].size(), 3u);
    const auto scene = evar::geometry::load_scene(out / "scene.json");
    ASSERT_EQ(scene.vessels.size(), 3u);
    EXPECT_EQ(scene.vessels[0].name, "aorta");
    EXPECT_EQ(scene.vessels[1].name, "iliac_right");
    // Head up in LPS, the right iliac to the patient's right (-x) of the left.
    EXPECT_GT(scene.vessels[0].centerline.front().z(), scene.vessels[0].centerline.back().z() + 20.0);
    EXPECT_LT(scene.vessels[1].centerline.back().x(), scene.vessels[2].centerline.back().x());
    // The pieces are the whole surface, split along the cuts: their areas add up to its.
    const auto area = [](const evar::geometry::TriangleMesh& m) {
      double a = 0.0;
      for (Eigen::Index f = 0; f < m.F.rows(); ++f)
        a += 0.5 * (m.V.row(m.F(f, 1)) - m.V.row(m.F(f, 0))).cross(m.V.row(m.F(f, 2)) - m.V.row(m.F(f, 0))).norm();
      return a;
    };
    const auto whole = evar::geometry::read_mesh(data / surface).mesh;
    double pieces = 0.0;
    for (const auto& v : scene.vessels) pieces += area(v.mesh.mesh);
    EXPECT_NEAR(pieces, area(whole), 1e-3 * area(whole));

    deform_with_pushed_wire(scene, out);
  }
}

// Read as LPS (it declares nothing), the data's aorta runs along +y, not to the head: refused,
// saying which axis and how to say what it is, with its centerlines or without (the computed
// ones run the same way).
TEST(CliScene, ASurfaceInImageAxesIsRefusedWithTheFix) {
  EVAR_VMTK_DATA_OR_SKIP(data);
  const evar::test::TempDir dir;
  const auto axes = evarnode({"scene", "--surface", (data / "aorta-surface.vtp").string(), "--centerlines",
                              (data / "aorta-centerline.vtp").string(), "--out", (dir.path / "a").string()});
  EXPECT_EQ(axes.code, 1);
  EXPECT_NE(axes.err.find("its aorta runs from the bifurcation to its inlet along the file's +y axis"), std::string::npos)
      << axes.err;
  EXPECT_NE(axes.err.find("--axes RSP"), std::string::npos) << axes.err;
  EXPECT_NE(axes.err.find("Nothing is rotated without being asked"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir.path / "a" / "scene.json"));

  const auto none = evarnode({"scene", "--surface", (data / "aorta-surface.vtp").string(), "--out", (dir.path / "b").string()});
  EXPECT_EQ(none.code, 1);
  EXPECT_NE(none.err.find("along the file's +y axis"), std::string::npos) << none.err;
  EXPECT_NE(none.err.find("--axes RSP"), std::string::npos) << none.err;
  EXPECT_FALSE(fs::exists(dir.path / "b" / "scene.json"));

  // The centerlines given as the surface, and the surface as the centerlines.
  const auto swapped = evarnode({"scene", "--surface", (data / "aorta-centerline.vtp").string(), "--centerlines",
                                 (data / "aorta-surface.vtp").string(), "--out", (dir.path / "c").string()});
  EXPECT_EQ(swapped.code, 1);
  EXPECT_NE(swapped.err.find("it looks like a centerline file"), std::string::npos) << swapped.err;
}

// 3D Slicer's way: the centerlines as markups curves (patient LPS, no radii), here VMTK's
// paths turned into LPS, plus a stub path from the aorta's middle to the patient's left:
// its ostium is offered as the landmark "renal_left", on the aortic wall.
TEST(CliScene, MarkupsCenterlinesWorkAndAStubPathGivesItsOstiumAsALandmark) {
  EVAR_VMTK_DATA_OR_SKIP(data);
  const evar::test::TempDir dir;
  const auto vmtk = evar::geometry::read_centerline_file(data / "aorta-centerline.vtp");
  // RSP: file x to the right (-x in LPS), y to the head (+z), z to the back (+y).
  const auto to_lps = [](const Eigen::Vector3d& p) { return Eigen::Vector3d(-p.x(), p.z(), p.y()); };
  std::vector<evar::geometry::Markup> curves;
  for (std::size_t c = 0; c < vmtk.curves.size(); ++c) {
    evar::geometry::Markup m{"Curve", std::string("path").append(std::to_string(c + 1)), {}};
    for (std::size_t i = 0; i < vmtk.curves[c].points.size(); ++i)
      m.points.push_back({std::string("p").append(std::to_string(i)), to_lps(vmtk.curves[c].points[i])});
    curves.push_back(m);
  }
  // The stub: along path 1 to its 30th point (the aorta's middle), then 25 mm to the left.
  evar::geometry::Markup stub{"Curve", "stub", {}};
  for (std::size_t i = 0; i <= 30; ++i) stub.points.push_back(curves[0].points[i]);
  const Eigen::Vector3d origin = stub.points.back().position_lps;
  for (int k = 1; k <= 50; ++k)
    stub.points.push_back({std::string("s").append(std::to_string(k)), origin + Eigen::Vector3d(0.5 * k, 0, 0)});
  curves.push_back(stub);
  evar::geometry::write_markups(dir.path / "centerlines.mrk.json", curves);

  const auto out = dir.path / "scene";
  const auto made = evarnode({"scene", "--surface", (data / "aorta-surface.vtp").string(), "--centerlines",
                              (dir.path / "centerlines.mrk.json").string(), "--axes", "RSP", "--out", out.string()});
  ASSERT_EQ(made.code, 0) << made.err;
  EXPECT_NE(made.err.find("the centerlines carry no radius: taken from the surface"), std::string::npos) << made.err;
  EXPECT_NE(made.err.find("1 side-branch stubs found along the centerlines"), std::string::npos) << made.err;
  const auto scene = evar::geometry::load_scene(out / "scene.json");
  ASSERT_EQ(scene.landmarks.size(), 1u);
  EXPECT_EQ(scene.landmarks[0].label, "renal_left");
  // On the aorta's left wall, beside where the stub leaves it.
  const auto& p = scene.landmarks[0].position_lps;
  EXPECT_GT(p.x(), origin.x() + 3.0);
  EXPECT_LT((p - origin).norm(), 15.0);
}

// The project's own segmentation-like surface (marching cubes of a label volume, staircase
// and slivers, side-branch stubs), in its image's axes with no tag and no centerlines: the
// scene is made (centerlines computed, the four stubs' ostia offered), deform takes it and
// the pushed wire ends inside. Needs no shared data.
TEST(CliScene, ASegmentationPhantomInImageAxesMakesASceneAndThePushedWireEndsInside) {
  // At the phantom's usual CT spacing, and at a thick-slice CT's, whose marching-cubes
  // surface has edges the paper's resolution already but slivers by the hundred.
  for (const Eigen::Vector3d& spacing : {Eigen::Vector3d(0.8, 0.8, 1.5), Eigen::Vector3d(0.9, 0.9, 2.0)}) {
    SCOPED_TRACE("spacing " + std::to_string(spacing.z()) + " mm between slices");
    const evar::test::TempDir dir;
    const auto phantom =
        evar::sim::make_segmentation_phantom({.spacing_mm = spacing, .frame = evar::sim::PhantomFrame::Image});
    const auto surface = dir.path / "segmentation.stl";
    evar::test::write_untagged_stl(surface, phantom.surface);
    const auto out = dir.path / "scene";
    const auto made = evarnode({"scene", "--surface", surface.string(), "--axes", "LIP", "--out", out.string()});
    ASSERT_EQ(made.code, 0) << made.err;
    EXPECT_NE(made.err.find("computed from the surface's mean-curvature-flow skeleton"), std::string::npos) << made.err;
    EXPECT_NE(made.err.find("4 side-branch stubs found"), std::string::npos) << made.err;
    const auto report = read_json(out / "scene_report.json");
    EXPECT_EQ(report["axes"], "LIP");
    const auto scene = evar::geometry::load_scene(out / "scene.json");
    ASSERT_EQ(scene.vessels.size(), 3u);
    EXPECT_EQ(scene.landmarks.size(), 4u);
    EXPECT_TRUE(fs::exists(out / "scene.png"));
    // A proxy file for every vessel whose proxy could be made (the phantom's thin renal stubs
    // sometimes fold the aorta's: then the report says why, and deform solves its own mesh).
    int proxy_files = 0;
    for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
      const bool kept = !scene.vessels[i].proxy_path.empty() && fs::exists(scene.vessels[i].proxy_path);
      proxy_files += kept;
      EXPECT_EQ(kept, report["vessels"][i]["proxy_refused"].get<std::string>().empty()) << scene.vessels[i].name;
    }
    EXPECT_EQ(report["proxy_files"], proxy_files);
    deform_with_pushed_wire(scene, out);
    if (spacing.z() != 1.5) continue;
    // A proxy file damaged (here overwritten with text): not used, made anew, said so with
    // the fix; the result stands.
    const auto with_file = std::find_if(scene.vessels.begin(), scene.vessels.end(),
                                        [](const auto& v) { return !v.proxy_path.empty(); });
    ASSERT_NE(with_file, scene.vessels.end()) << "no vessel kept a proxy file";
    std::ofstream(with_file->proxy_path, std::ios::trunc) << "solid not a proxy\n";
    const auto stale = evarnode({"deform", "--scene", (out / "scene.json").string(), "--device", (out / "wire.mrk.json").string(),
                                 "--out", (dir.path / "stale").string(), "--strict", "--no-preview"});
    EXPECT_EQ(stale.code, 0) << stale.err;
    EXPECT_NE(stale.err.find(with_file->name + ": the scene's proxy file was not used, the proxy was made anew"), std::string::npos)
        << stale.err;
    EXPECT_NE(stale.err.find("`evarnode proxies --scene " + (out / "scene.json").string() + "` keeps a fresh one"), std::string::npos)
        << stale.err;
    EXPECT_NE(stale.err.find("not an evarnode proxy file"), std::string::npos);
  }
}
