// `evarnode deform` and `evarnode arap` on the example scene: outputs, formats kept, bad input named.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "support/cli_fixture.hpp"
#include "evar/geometry/closest_point.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/ray_caster.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/geometry/xa_dicom.hpp"
#include "evar/sim/fluoro_render.hpp"

#include <opencv2/imgcodecs.hpp>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <iterator>
#include <map>
#include "evar/session/session.hpp"
#include "evar/sim/example_scene.hpp"
#include "geometry/synthetic_fluoro.hpp"

namespace fs = std::filesystem;
using evar::test::Cli;
using evar::test::evarnode;
using evar::test::write_text;
using evar::app::run_cli;

namespace {

// ARAP energy of `moved` against `rest`, written out plainly (no solver code).
double arap_energy(const evar::geometry::TriangleMesh& rest, const Eigen::MatrixXd& moved) {
  const Eigen::Index n = rest.V.rows();
  std::vector<std::map<int, double>> w(static_cast<std::size_t>(n));
  for (Eigen::Index f = 0; f < rest.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = rest.F(f, k), b = rest.F(f, (k + 1) % 3), c = rest.F(f, (k + 2) % 3);
      const Eigen::Vector3d u = rest.V.row(a) - rest.V.row(c), v = rest.V.row(b) - rest.V.row(c);
      const double cot = u.dot(v) / u.cross(v).norm();  // the angle at c, opposite edge ab
      w[static_cast<std::size_t>(a)][b] += 0.5 * cot;
      w[static_cast<std::size_t>(b)][a] += 0.5 * cot;
    }
  double E = 0.0;
  for (Eigen::Index i = 0; i < n; ++i) {
    Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
    for (const auto& [j, wij] : w[static_cast<std::size_t>(i)])
      S += wij * (rest.V.row(i) - rest.V.row(j)).transpose() * (moved.row(i) - moved.row(j));
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(S, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
    D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
    const Eigen::Matrix3d R = svd.matrixV() * D * svd.matrixU().transpose();
    for (const auto& [j, wij] : w[static_cast<std::size_t>(i)])
      E += wij * ((moved.row(i) - moved.row(j)).transpose() - R * (rest.V.row(i) - rest.V.row(j)).transpose()).squaredNorm();
  }
  return E;
}

}  // namespace

TEST_F(Cli, DeformWritesMeshesLandmarksReportAndPreview) {
  const auto out = scratch("deform_ok");
  const auto r = evarnode({"deform", "--scene", scene().string(), "--device", device().string(), "--out", out.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* f : {"aorta.stl", "iliac_left.stl", "iliac_right.stl", "landmarks.mrk.json", "report.json", "preview.png"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  std::ifstream in(out / "report.json");
  const auto report = nlohmann::json::parse(in);
  EXPECT_EQ(report["device_iliac"], "iliac_right");
  EXPECT_EQ(report["coarse_rotations"], true);
  ASSERT_EQ(report["vessels"].size(), 3u);
  for (const auto& v : report["vessels"]) {
    for (const char* key : {"control_points", "skeleton_points", "iterations", "final_energy"}) EXPECT_TRUE(v.contains(key)) << key;
    for (const char* key : {"weights", "control_points", "skeleton", "factor", "iterate", "total"})
      EXPECT_TRUE(v["timings_ms"].contains(key)) << key;
    // How far the bound top of an iliac lies from the aortic wall; nothing to say for the aorta.
    if (v["kind"] == "iliac") {
      ASSERT_TRUE(v["junction_gap_mm"].is_number()) << v["name"];
      EXPECT_GE(v["junction_gap_mm"].get<double>(), 0.0);
      EXPECT_LT(v["junction_gap_mm"].get<double>(), 30.0) << v["name"];
    } else {
      EXPECT_TRUE(v["junction_gap_mm"].is_null());
    }
  }
  // The example's device ends inside the adapted vessels: nothing outside, and the log
  // gives no warning of it.
  EXPECT_EQ(report["device_outside_length_mm"].get<double>(), 0.0);
  EXPECT_EQ(report["device_outside_max_depth_mm"].get<double>(), 0.0);
  EXPECT_GT(report["device_containment"]["device_length_mm"].get<double>(), 100.0);
  EXPECT_TRUE(report["device_containment"]["stretches"].empty());
  EXPECT_EQ(r.err.find("outside the vessels"), std::string::npos) << r.err;
  // Same vertex count and order in the output (welded STL re-read).
  const auto before = evar::geometry::read_mesh(dir_ / "iliac_right.stl").mesh;
  const auto after = evar::geometry::read_mesh(out / "iliac_right.stl").mesh;
  EXPECT_EQ(before.V.rows(), after.V.rows());
}

// --pelvis-shift-mm moves the models with the pelvis before they are bent: the report says by
// how much and between which points it ramped, "before" stays the registered landmark, and
// the internal iliac ostium of the iliac without the device (held by the tether to its
// shifted pose, its top following the aorta) lands about the shift further down than without.
TEST_F(Cli, DeformMovesTheModelsWithAGivenPelvisShiftBeforeBendingThem) {
  const auto plain = scratch("deform_no_pelvis_shift");
  const auto shifted = scratch("deform_pelvis_shift");
  ASSERT_EQ(evarnode({"deform", "--scene", scene().string(), "--device", device().string(), "--out", plain.string(), "--no-preview"}).code, 0);
  const auto r = evarnode({"deform", "--scene", scene().string(), "--device", device().string(), "--out", shifted.string(),
                           "--no-preview", "--pelvis-shift-mm", "0", "0", "-8"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("pelvis shifted by (0.0, 0.0, -8.0) mm"), std::string::npos) << r.err;
  const auto read = [](const fs::path& f) { std::ifstream in(f); return nlohmann::json::parse(in); };
  const auto a = read(plain / "report.json"), b = read(shifted / "report.json");
  EXPECT_TRUE(a["pelvis_shift"].is_null());
  ASSERT_TRUE(b["pelvis_shift"].is_object());
  EXPECT_EQ(b["pelvis_shift"]["shift_mm"], nlohmann::json({0.0, 0.0, -8.0}));
  EXPECT_GT(b["pelvis_shift"]["renal_point_mm"][2].get<double>(), b["pelvis_shift"]["bifurcation_point_mm"][2].get<double>());
  const auto find = [](const nlohmann::json& report, const std::string& label) {
    for (const auto& lm : report["landmarks"])
      if (lm["label"] == label) return lm;
    return nlohmann::json();
  };
  for (const char* label : {"renal_left", "renal_right", "internal_iliac_left", "internal_iliac_right"})
    EXPECT_EQ(find(a, label)["before_lps_mm"], find(b, label)["before_lps_mm"]) << label;
  const double dz = find(b, "internal_iliac_left")["after_lps_mm"][2].get<double>() -
                    find(a, "internal_iliac_left")["after_lps_mm"][2].get<double>();
  EXPECT_NEAR(dz, -8.0, 2.0);
  EXPECT_NEAR(find(b, "renal_left")["after_lps_mm"][2].get<double>(), find(a, "renal_left")["after_lps_mm"][2].get<double>(), 0.5);
  // Three numbers or none.
  EXPECT_NE(evarnode({"deform", "--scene", scene().string(), "--device", device().string(), "--out", shifted.string(),
                      "--pelvis-shift-mm", "0", "-8"}).code, 0);
}

// A vessel too thin for the asked proxy edge, and for the finer ones tried after it, is solved
// on its own mesh; the run says so in the log and in report.json, and still writes every
// vessel. At a 14 mm proxy edge the suite's small example scene gets the aorta's proxy at that edge
// and none for the iliacs (4.5-6 mm radius) at any rung (14, 11.2, 8.96 mm): each says so in
// report.json, and the log names the vessels solved on their own meshes.
TEST_F(Cli, DeformSaysWhichVesselsItCouldNotSolveOnAProxy) {
  const auto out = scratch("deform_proxy_refused");
  const auto r = evarnode({"deform", "--scene", scene().string(), "--device", device().string(), "--out", out.string(),
                           "--no-preview", "--proxy-edge-mm", "14"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto report = nlohmann::json::parse(std::ifstream(out / "report.json"));
  EXPECT_EQ(report["proxy_edge_mm"], 14.0);
  ASSERT_EQ(report["vessels"].size(), 3u);
  for (const auto& v : report["vessels"]) {
    const std::string name = v["name"];
    EXPECT_TRUE(fs::exists(out / (name + ".stl"))) << name;
    if (name == "aorta") {
      EXPECT_GT(v["proxy_vertices"].get<int>(), 0);
      EXPECT_EQ(v["proxy_edge_mm"], 14.0);
      EXPECT_EQ(v["proxy_refused"], "");
    } else {
      EXPECT_EQ(v["proxy_vertices"], 0) << name;
      EXPECT_TRUE(v["proxy_edge_mm"].is_null()) << name;
      EXPECT_NE(v["proxy_refused"].get<std::string>().find("thinner than the proxy's edge"), std::string::npos) << name;
      EXPECT_NE(v["proxy_refused"].get<std::string>().find("; at 8.96 mm: "), std::string::npos) << name;
      EXPECT_NE(r.err.find(name + ": solved on its own"), std::string::npos) << r.err;
    }
  }
  EXPECT_NE(r.err.find("aorta        solved on a proxy of"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("edges of about 14 mm"), std::string::npos) << r.err;
}

// A scene put together without `evarnode scene` names no proxy files: deform makes the
// proxies at every load and says how to keep them; `proxies` keeps them beside the meshes
// and names them in scene.json (nothing else in it changed), deform then reads them with
// the same result, and a second `proxies` finds them current and rewrites nothing. (At a
// 14 mm edge the suite's small scene has a proxy for its aorta only, which keeps it fast.)
TEST_F(Cli, ProxiesKeepsAHandMadeScenesProxiesAndDeformReadsThemWithTheSameResult) {
  const auto dir = scratch("proxies_scene");
  evar::sim::ExampleSceneParams p;
  p.aorta_vertices = 2500;
  p.iliac_vertices = 1500;
  evar::sim::write_example_scene(evar::sim::make_example_scene(p), dir);
  const auto json = dir / "scene.json";
  const auto manifest_before = nlohmann::json::parse(std::ifstream(json));
  const auto deform_once = [&](const std::string& name) {
    const auto out = scratch(name);
    const auto r = evarnode({"deform", "--scene", json.string(), "--device", (dir / "device.mrk.json").string(), "--out",
                             out.string(), "--no-preview", "--proxy-edge-mm", "14"});
    EXPECT_EQ(r.code, 0) << r.err;
    return std::pair{r.err, nlohmann::json::parse(std::ifstream(out / "report.json"))};
  };
  const auto [made_log, made] = deform_once("proxies_made");
  EXPECT_EQ(made["vessels"][0]["proxy_file"], "");
  EXPECT_NE(made_log.find("1 proxy made at load"), std::string::npos) << made_log;
  // The command to keep them, at this call's edge (a file made at another edge is not read).
  EXPECT_NE(made_log.find("`evarnode proxies --scene " + json.string() + " --proxy-edge-mm 14`"), std::string::npos)
      << made_log;

  const auto kept = evarnode({"proxies", "--scene", json.string(), "--proxy-edge-mm", "14"});
  ASSERT_EQ(kept.code, 0) << kept.err;
  EXPECT_TRUE(fs::is_regular_file(dir / "aorta.proxy"));
  EXPECT_NE(kept.err.find("iliac_left: no proxy could be made"), std::string::npos) << kept.err;
  EXPECT_NE(kept.err.find("scene.json names 1 proxy file(s)"), std::string::npos) << kept.err;
  auto manifest = nlohmann::json::parse(std::ifstream(json));
  EXPECT_EQ(manifest["vessels"][0]["proxy"], "aorta.proxy");
  for (const std::size_t i : {1u, 2u}) EXPECT_FALSE(manifest["vessels"][i].contains("proxy")) << i;
  manifest["vessels"][0].erase("proxy");
  EXPECT_EQ(manifest, manifest_before);

  const auto [read_log, read] = deform_once("proxies_read");
  EXPECT_EQ(fs::path(read["vessels"][0]["proxy_file"].get<std::string>()).filename(), "aorta.proxy");
  EXPECT_EQ(read_log.find("made at load"), std::string::npos) << read_log;
  ASSERT_EQ(read["landmarks"].size(), made["landmarks"].size());
  for (std::size_t k = 0; k < made["landmarks"].size(); ++k)
    EXPECT_EQ(read["landmarks"][k]["after_lps_mm"], made["landmarks"][k]["after_lps_mm"]) << k;

  const std::string before_again = [&] {
    std::ifstream in(json);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }();
  const auto again = evarnode({"proxies", "--scene", json.string(), "--proxy-edge-mm", "14"});
  ASSERT_EQ(again.code, 0) << again.err;
  EXPECT_NE(again.err.find("is current: kept as it is"), std::string::npos) << again.err;
  std::ifstream in(json);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), before_again);

  // At an edge no vessel can be remeshed to, the aorta has no proxy any more: the entry that
  // names its file would be stale, and is removed.
  const auto none = evarnode({"proxies", "--scene", json.string(), "--proxy-edge-mm", "200"});
  ASSERT_EQ(none.code, 0) << none.err;
  EXPECT_NE(none.err.find("aorta: no proxy could be made"), std::string::npos) << none.err;
  EXPECT_EQ(nlohmann::json::parse(std::ifstream(json)), manifest_before);
}

TEST_F(Cli, DeformWithoutCoarseRotationsSaysSoAndIteratesTheIliacsPlainly) {
  const auto with = scratch("deform_coarse"), without = scratch("deform_plain");
  ASSERT_EQ(evarnode({"deform", "--scene", scene().string(), "--device", device().string(), "--out", with.string(),
                      "--no-preview"}).code, 0);
  const auto r = evarnode({"deform", "--scene", scene().string(), "--device", device().string(), "--out",
                           without.string(), "--no-preview", "--no-coarse-rotations"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto a = nlohmann::json::parse(std::ifstream(with / "report.json"));
  const auto b = nlohmann::json::parse(std::ifstream(without / "report.json"));
  EXPECT_EQ(b["coarse_rotations"], false);
  // The aorta has no coarse space: the same iterations either way. The carrier iliac's differ.
  for (std::size_t i = 0; i < a["vessels"].size(); ++i) {
    const auto& va = a["vessels"][i];
    const auto& vb = b["vessels"][i];
    // Without a coarse space no step can fall back from one.
    EXPECT_EQ(vb["coarse_fallbacks"], 0) << vb["name"];
    EXPECT_LE(va["coarse_fallbacks"].get<int>(), va["iterations"].get<int>()) << va["name"];
    if (va["name"] == "aorta") {
      EXPECT_EQ(va["iterations"], vb["iterations"]);
      EXPECT_EQ(va["coarse_fallbacks"], 0);
    }
    if (va["name"] == a["device_iliac"]) {
      EXPECT_NE(va["iterations"], vb["iterations"]);
    }
  }
}

TEST_F(Cli, MissingSceneFileIsNamed) {
  const auto r = evarnode({"deform", "--scene", "/nonexistent/scene.json", "--device", device().string(), "--out",
                           scratch("missing").string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("/nonexistent/scene.json"), std::string::npos) << r.err;
}

TEST_F(Cli, BadJsonIsNamedWithItsFile) {
  const auto dir = scratch("badjson");
  write_text(dir / "scene.json", "{\"format\": \"evarnode-scene\", \"version\": 1,,}");
  const auto r = evarnode({"deform", "--scene", (dir / "scene.json").string(), "--device", device().string(), "--out",
                           (dir / "out").string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("scene.json"), std::string::npos) << r.err;
}

TEST_F(Cli, EmptyDeviceIsRefused) {
  const auto dir = scratch("empty_device");
  write_text(dir / "device.mrk.json", curve_json(""));
  const auto r = evarnode({"deform", "--scene", scene().string(), "--device", (dir / "device.mrk.json").string(),
                           "--out", (dir / "out").string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("device.mrk.json"), std::string::npos) << r.err;
}

TEST_F(Cli, NonNumericDeviceCoordinateIsRefused) {
  const auto dir = scratch("nan_device");
  write_text(dir / "device.mrk.json", curve_json(R"({"position": [0, 0, 0]}, {"position": [null, 0, 10]})"));
  const auto r = evarnode({"deform", "--scene", scene().string(), "--device", (dir / "device.mrk.json").string(),
                           "--out", (dir / "out").string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("device.mrk.json"), std::string::npos) << r.err;
}

TEST_F(Cli, DeviceFarFromEveryVesselIsRefused) {
  const auto dir = scratch("far_device");
  write_text(dir / "device.mrk.json", curve_json(R"({"position": [400, 0, 0]}, {"position": [400, 0, 50]})"));
  const auto r = evarnode({"deform", "--scene", scene().string(), "--device", (dir / "device.mrk.json").string(),
                           "--out", (dir / "out").string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("no part of the device lies in any vessel"), std::string::npos) << r.err;
}

TEST_F(Cli, NonManifoldMeshIsNamed) {
  const auto dir = scratch("nonmanifold");
  // Three triangles on one edge (0-1).
  write_text(dir / "fan.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n");
  write_text(dir / "c.json", R"({"fixed": [0]})");
  const auto r = evarnode({"arap", "--mesh", (dir / "fan.obj").string(), "--constraints", (dir / "c.json").string(),
                           "--out", (dir / "o.obj").string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("fan.obj"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("non-manifold"), std::string::npos) << r.err;
}

TEST_F(Cli, ArapSolvesExplicitConstraintsAndReports) {
  const auto dir = scratch("arap");
  const auto aorta = dir_ / "iliac_left.stl";
  const auto mesh = evar::geometry::read_mesh(aorta).mesh;
  nlohmann::json c = {{"fixed", {0, 1, 2}}, {"handles", nlohmann::json::array()}};
  const int v = static_cast<int>(mesh.V.rows()) - 1;
  c["handles"].push_back({{"vertex", v}, {"target", {mesh.V(v, 0) + 5.0, mesh.V(v, 1), mesh.V(v, 2)}}});
  write_text(dir / "c.json", c.dump());
  const auto r = evarnode({"arap", "--mesh", aorta.string(), "--constraints", (dir / "c.json").string(), "--out",
                           (dir / "out.ply").string(), "--report", (dir / "r.json").string()});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto out = evar::geometry::read_mesh(dir / "out.ply").mesh;
  ASSERT_EQ(out.V.rows(), mesh.V.rows());
  EXPECT_NEAR(out.V(v, 0), mesh.V(v, 0) + 5.0, 1e-9);  // the handle reached its target
  std::ifstream in(dir / "r.json");
  const auto rep = nlohmann::json::parse(in);
  for (const char* key : {"factor_ms", "iterations", "iterate_ms", "per_iteration_ms", "energy"})
    EXPECT_TRUE(rep.contains(key)) << key;
  // The energy reported is the documented one (docs/DEFORMATION.md), recomputed here from
  // the two meshes alone: Σ_i Σ_j∈N(i) w_ij |e'_ij − R_i e_ij|², w_ij = (cot α + cot β)/2,
  // R_i the best rotation of vertex i. Users compare it with other ARAP implementations.
  EXPECT_NEAR(rep["energy"].get<double>(), arap_energy(mesh, out.V), 1e-9 * arap_energy(mesh, out.V));
  EXPECT_GT(arap_energy(mesh, out.V), 0.0);  // the handle moved: not a rigid motion
}

TEST_F(Cli, ConstraintIndexOutOfRangeIsNamed) {
  const auto dir = scratch("arap_bad");
  write_text(dir / "c.json", R"({"handles": [{"vertex": 99999999, "target": [0, 0, 0]}]})");
  const auto r = evarnode({"arap", "--mesh", (dir_ / "iliac_left.stl").string(), "--constraints",
                           (dir / "c.json").string(), "--out", (dir / "o.stl").string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("handles[0]"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("out of range"), std::string::npos) << r.err;
}

TEST_F(Cli, UsageErrorsExitWithTwo) {
  EXPECT_EQ(evarnode({"deform", "--scene", "x.json"}).code, 2);
  EXPECT_EQ(evarnode({"no-such-command"}).code, 2);
}

TEST_F(Cli, DeformRefusesToOverwriteItsInputs) {
  const auto r = evarnode({"deform", "--scene", scene().string(), "--device", device().string(), "--out", dir_.string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("would overwrite an input"), std::string::npos) << r.err;
}

// `deform` writes each mesh in its input's format, with the file's vertex order and faces
// (PLY and VTK are indexed formats), the iliac carrying the device moved.
void evar::test::Cli::expect_deform_keeps(evar::geometry::MeshFormat format, const std::string& extension) {
  const auto dir = scratch("format" + extension);
  evar::sim::ExampleSceneParams p;
  p.aorta_vertices = 2500;
  p.iliac_vertices = 1500;
  evar::sim::write_example_scene(evar::sim::make_example_scene(p), dir / "in", format);
  const auto r = evarnode({"deform", "--scene", (dir / "in" / "scene.json").string(), "--device",
                           (dir / "in" / "device.mrk.json").string(), "--out", (dir / "out").string(), "--no-preview"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto in = evar::geometry::read_mesh(dir / "in" / ("iliac_right" + extension));
  const auto out = evar::geometry::read_mesh(dir / "out" / ("iliac_right" + extension));
  EXPECT_EQ(out.format, format);
  ASSERT_EQ(out.mesh.V.rows(), in.mesh.V.rows());
  EXPECT_EQ(out.mesh.F, in.mesh.F);
  EXPECT_GT((out.mesh.V - in.mesh.V).cwiseAbs().maxCoeff(), 0.1);
}

TEST_F(Cli, DeformKeepsThePlyFormatOfItsInput) { expect_deform_keeps(evar::geometry::MeshFormat::PlyBinary, ".ply"); }

// 3D Slicer's default model format, VTK legacy polydata, in and out.
TEST_F(Cli, DeformKeepsTheVtkFormatOfItsInput) { expect_deform_keeps(evar::geometry::MeshFormat::VtkBinary, ".vtk"); }
TEST_F(Cli, DeformKeepsTheVtpFormatOfItsInput) { expect_deform_keeps(evar::geometry::MeshFormat::Vtp, ".vtp"); }

// A scene whose meshes were saved from 3D Slicer in RAS (SPACE=RAS in each header; the
// centerlines, device and landmarks stay LPS markups) deforms exactly as the LPS scene,
// and its output meshes are written back in RAS, saying so. Read as LPS, each mesh would
// lie mirrored through the patient's long axis, off its centerline.
TEST_F(Cli, DeformReadsMeshesSavedInRasAndWritesThemBackInRas) {
  namespace geometry = evar::geometry;
  const auto dir = scratch("ras_scene");
  fs::copy(dir_, dir / "in", fs::copy_options::recursive);
  for (const char* name : {"aorta.stl", "iliac_left.stl", "iliac_right.stl"}) {
    const auto lps = geometry::read_mesh(dir_ / name);
    geometry::write_mesh(dir / "in" / name, lps.mesh, lps.format, geometry::MeshSpace::Ras);
  }
  const auto lps_run = evarnode({"deform", "--scene", scene().string(), "--device", device().string(), "--out",
                                 (dir / "out_lps").string(), "--no-preview"});
  ASSERT_EQ(lps_run.code, 0) << lps_run.err;
  const auto ras_run = evarnode({"deform", "--scene", (dir / "in" / "scene.json").string(), "--device",
                                 (dir / "in" / "device.mrk.json").string(), "--out", (dir / "out_ras").string(),
                                 "--no-preview"});
  ASSERT_EQ(ras_run.code, 0) << ras_run.err;
  for (const char* name : {"aorta.stl", "iliac_left.stl", "iliac_right.stl"}) {
    const auto from_lps = geometry::read_mesh(dir / "out_lps" / name);
    const auto from_ras = geometry::read_mesh(dir / "out_ras" / name);
    EXPECT_EQ(from_lps.space, geometry::MeshSpace::Lps) << name;
    EXPECT_EQ(from_ras.space, geometry::MeshSpace::Ras) << name;
    // The same numbers in (a sign flip is exact), the same arithmetic, the same floats out.
    ASSERT_EQ(from_ras.mesh.V.rows(), from_lps.mesh.V.rows()) << name;
    EXPECT_EQ((from_ras.mesh.V - from_lps.mesh.V).cwiseAbs().maxCoeff(), 0.0) << name;
  }
  std::ifstream a(dir / "out_lps" / "landmarks.mrk.json"), b(dir / "out_ras" / "landmarks.mrk.json");
  EXPECT_EQ(nlohmann::json::parse(a), nlohmann::json::parse(b));
}

// arap's targets are in the mesh file's own coordinates, RAS for a file that says so.
TEST_F(Cli, ArapTakesTargetsInTheCoordinatesOfAMeshSavedInRas) {
  namespace geometry = evar::geometry;
  const auto dir = scratch("arap_ras");
  const auto lps = geometry::read_mesh(dir_ / "iliac_left.stl").mesh;
  geometry::write_mesh(dir / "in.ply", lps, geometry::MeshFormat::PlyAscii, geometry::MeshSpace::Ras);
  const int v = static_cast<int>(lps.V.rows()) - 1;
  // Vertex v in the file: (-x, -y, z) of its LPS position; moved 5 mm along the file's x.
  nlohmann::json c = {{"fixed", {0, 1, 2}}, {"handles", nlohmann::json::array()}};
  c["handles"].push_back({{"vertex", v}, {"target", {-lps.V(v, 0) + 5.0, -lps.V(v, 1), lps.V(v, 2)}}});
  write_text(dir / "c.json", c.dump());
  const auto r = evarnode({"arap", "--mesh", (dir / "in.ply").string(), "--constraints", (dir / "c.json").string(),
                           "--out", (dir / "out.ply").string()});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto out = geometry::read_mesh(dir / "out.ply");
  EXPECT_EQ(out.space, geometry::MeshSpace::Ras);
  EXPECT_NEAR(out.mesh.V(v, 0), lps.V(v, 0) - 5.0, 1e-9);  // file +x is patient right: LPS -x
  EXPECT_NEAR(out.mesh.V(v, 1), lps.V(v, 1), 1e-9);
  EXPECT_NEAR(out.mesh.V(0, 0), lps.V(0, 0), 1e-9);  // a fixed vertex stays
}

TEST_F(Cli, ArapRefusesToWriteANonFiniteResult) {
  const auto dir = scratch("arap_overflow");
  write_text(dir / "c.json", R"({"fixed": [0], "handles": [{"vertex": 5, "target": [1e308, 1e308, 1e308]}]})");
  const auto r = evarnode({"arap", "--mesh", (dir_ / "iliac_left.stl").string(), "--constraints",
                           (dir / "c.json").string(), "--out", (dir / "o.stl").string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("non-finite"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "o.stl"));
}

TEST_F(Cli, ArapRefusesUnknownConstraintKeys) {
  const auto dir = scratch("arap_typo");
  write_text(dir / "c.json", R"({"fixd": [0], "handles": [{"vertex": 5, "target": [0, 0, 0]}]})");
  const auto r = evarnode({"arap", "--mesh", (dir_ / "iliac_left.stl").string(), "--constraints",
                           (dir / "c.json").string(), "--out", (dir / "o.stl").string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("unknown key \"fixd\""), std::string::npos) << r.err;
}

// A device that runs far out of the aorta's side (a reconstruction gone astray, a wrong
// registration), farther than the deformation can follow: the vessels are written as
// adapted, and the run says how much of the device they leave outside, where, and how deep;
// with --strict it exits 4 after writing everything.
TEST_F(Cli, DeformSaysWhenItLeavesTheDeviceOutsideAndStrictExitsFour) {
  const auto scene_files = evar::geometry::load_scene(scene());
  const auto& aorta = *std::find_if(scene_files.vessels.begin(), scene_files.vessels.end(),
                                    [](const auto& v) { return v.name == "aorta"; });
  auto curve = evar::geometry::read_curve(device(), 2);
  // The device's points within 6 mm of its point nearest the middle of the aortic
  // centerline are moved 120 mm to the patient's left.
  const Eigen::Vector3d middle = aorta.centerline[aorta.centerline.size() / 2];
  Eigen::Vector3d mid = curve.points.front().position_lps;
  for (const auto& p : curve.points)
    if ((p.position_lps - middle).norm() < (mid - middle).norm()) mid = p.position_lps;
  int pushed = 0;
  for (auto& p : curve.points)
    if ((p.position_lps - mid).norm() < 6.0) p.position_lps += Eigen::Vector3d(120.0, 0.0, 0.0), ++pushed;
  ASSERT_GE(pushed, 2);
  const auto bent = scratch("perforating") / "device.mrk.json";
  fs::create_directories(bent.parent_path());
  evar::geometry::write_markups(bent, {curve});

  const auto out = scratch("deform_outside");
  const auto r = evarnode({"deform", "--scene", scene().string(), "--device", bent.string(), "--out", out.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("of the device lies outside the vessels"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("beyond the wall of 'aorta'"), std::string::npos) << r.err;
  std::ifstream in(out / "report.json");
  const auto report = nlohmann::json::parse(in);
  const double depth = report["device_outside_max_depth_mm"].get<double>();
  const double length = report["device_outside_length_mm"].get<double>();
  // The aorta follows the device part of the way (measured: 84 mm), not all of it.
  EXPECT_GT(depth, 5.0);
  EXPECT_LT(depth, 120.0);
  EXPECT_GT(length, 30.0);
  ASSERT_FALSE(report["device_containment"]["stretches"].empty());
  EXPECT_EQ(report["device_containment"]["stretches"][0]["nearest_vessel"], "aorta");

  const auto strict = scratch("deform_outside_strict");
  const auto s = evarnode({"deform", "--scene", scene().string(), "--device", bent.string(), "--out", strict.string(),
                           "--strict", "--no-preview"});
  EXPECT_EQ(s.code, 4) << s.err;
  for (const char* f : {"aorta.stl", "iliac_left.stl", "iliac_right.stl", "landmarks.mrk.json", "report.json"})
    EXPECT_TRUE(fs::exists(strict / f)) << f;
  // --strict with a contained device exits 0.
  const auto fine = evarnode({"deform", "--scene", scene().string(), "--device", device().string(), "--out",
                              scratch("deform_strict_ok").string(), "--strict", "--no-preview"});
  EXPECT_EQ(fine.code, 0) << fine.err;
}

// Three dangerous scenes that used to pass silently, each refused by name with the fix:
// one surface given for every vessel, a vessel inside another, and a centerline file
// holding a whole tree of curves. And a mesh reaching far past its centerline.
TEST_F(Cli, ScenesWithOneSurfaceForSeveralVesselsOrACenterlineTreeInOneFileAreRefused) {
  const auto dir = scratch("dangerous_scenes");
  const auto scene_with = [&](const std::string& name, const std::string& right_mesh, const std::string& right_centerline) {
    const auto path = dir / (name + ".json");
    write_text(path, R"({"format": "evarnode-scene", "version": 1, "coordinate_system": "LPS", "units": "mm",
      "vessels": [
        {"name": "aorta", "kind": "aorta", "mesh": ")" + (dir_ / "aorta.stl").string() + R"(",
         "centerline": ")" + (dir_ / "aorta.centerline.mrk.json").string() + R"("},
        {"name": "iliac_right", "kind": "iliac", "mesh": ")" + right_mesh + R"(", "centerline": ")" + right_centerline + R"("}],
      "device_thickness_mm": 0.9})");
    return path;
  };
  const auto deform = [&](const fs::path& scene) {
    return evarnode({"deform", "--scene", scene.string(), "--device", device().string(), "--out",
                     (dir / "out").string(), "--no-preview"});
  };
  const std::string right_centerline = (dir_ / "iliac_right.centerline.mrk.json").string();

  // The aorta's surface given again for the iliac.
  const auto same = deform(scene_with("same", (dir_ / "aorta.stl").string(), right_centerline));
  EXPECT_EQ(same.code, 1);
  EXPECT_NE(same.err.find("vessels 'aorta' and 'iliac_right' have the same mesh (aorta.stl, aorta.stl)"), std::string::npos)
      << same.err;

  // A copy of the aorta shrunk into it, as the iliac.
  auto shrunk = evar::geometry::read_mesh(dir_ / "aorta.stl").mesh;
  const Eigen::RowVector3d centre = shrunk.V.colwise().mean();
  for (Eigen::Index i = 0; i < shrunk.V.rows(); ++i) shrunk.V.row(i) = centre + 0.5 * (shrunk.V.row(i) - centre);
  evar::geometry::write_mesh(dir / "inner.stl", shrunk, evar::geometry::MeshFormat::StlBinary);
  const auto nested = deform(scene_with("nested", (dir / "inner.stl").string(), right_centerline));
  EXPECT_EQ(nested.code, 1);
  EXPECT_NE(nested.err.find("the mesh of vessel 'iliac_right' (inner.stl) lies inside or on that of 'aorta' (aorta.stl)"),
            std::string::npos)
      << nested.err;

  // The iliac's centerline cut to its first half: its mesh reaches far past it.
  auto curve = evar::geometry::read_curve(right_centerline, 2);
  curve.points.resize(curve.points.size() / 2);
  evar::geometry::write_markups(dir / "short.mrk.json", {curve});
  const auto past = deform(scene_with("past", (dir_ / "iliac_right.stl").string(), (dir / "short.mrk.json").string()));
  EXPECT_EQ(past.code, 1);
  EXPECT_NE(past.err.find("the mesh of vessel 'iliac_right' (iliac_right.stl) reaches"), std::string::npos) << past.err;
  EXPECT_NE(past.err.find("past the distal end of its centerline (short.mrk.json"), std::string::npos) << past.err;

  // Every centerline in one file, as Slicer can save a whole tree.
  std::vector<evar::geometry::Markup> tree;
  for (const char* v : {"aorta", "iliac_left", "iliac_right"}) {
    auto c = evar::geometry::read_curve(dir_ / (std::string(v) + ".centerline.mrk.json"), 2);
    c.name = v;
    tree.push_back(c);
  }
  evar::geometry::write_markups(dir / "tree.mrk.json", tree);
  const auto several = deform(scene_with("tree", (dir_ / "iliac_right.stl").string(), (dir / "tree.mrk.json").string()));
  EXPECT_EQ(several.code, 1);
  EXPECT_NE(several.err.find("tree.mrk.json: holds 3 curves ('aorta', 'iliac_left', 'iliac_right') where one is expected"),
            std::string::npos)
      << several.err;
}
