#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "evar/app/cli.hpp"
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
#include "support/killed_recording.hpp"
#include "support/ramp_frames.hpp"

namespace fs = std::filesystem;
using evar::app::run_cli;

namespace {

struct Run {
  int code;
  std::string err;
};

Run evarnode(const std::vector<std::string>& args) {
  testing::internal::CaptureStderr();
  testing::internal::CaptureStdout();
  const int code = run_cli(args);
  testing::internal::GetCapturedStdout();
  return {code, testing::internal::GetCapturedStderr()};
}

void write_text(const fs::path& p, const std::string& text) {
  std::ofstream(p) << text;
}

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

// A small example scene, written once for the whole suite.
class Cli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // Per process: ctest runs each test in its own process, in parallel.
    dir_ = fs::path(testing::TempDir()) / ("evar_cli_example_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    evar::sim::ExampleSceneParams p;
    p.aorta_vertices = 2500;
    p.iliac_vertices = 1500;
    evar::sim::write_example_scene(evar::sim::make_example_scene(p), dir_);
  }
  static fs::path dir_;
  fs::path scene() const { return dir_ / "scene.json"; }
  fs::path device() const { return dir_ / "device.mrk.json"; }
  fs::path scratch(const std::string& name) const {
    const auto p = fs::path(testing::TempDir()) / ("evar_cli_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(p);
    fs::create_directories(p);
    return p;
  }
  void expect_deform_keeps(evar::geometry::MeshFormat format, const std::string& extension);
  std::string curve_json(const std::string& points) const {
    return R"({"markups": [{"type": "Curve", "coordinateSystem": "LPS", "controlPoints": [)" + points + "]}]}";
  }
};
fs::path Cli::dir_;

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
  // Same vertex count and order in the output (welded STL re-read).
  const auto before = evar::geometry::read_mesh(dir_ / "iliac_right.stl").mesh;
  const auto after = evar::geometry::read_mesh(out / "iliac_right.stl").mesh;
  EXPECT_EQ(before.V.rows(), after.V.rows());
}

// A vessel too thin for the asked proxy edge is solved on its own mesh; the run says so in
// the log and in report.json, and still writes every vessel.
TEST_F(Cli, DeformSaysWhichVesselsItCouldNotSolveOnAProxy) {
  const auto out = scratch("deform_proxy_refused");
  const auto r = evarnode({"deform", "--scene", scene().string(), "--device", device().string(), "--out", out.string(),
                           "--no-preview", "--proxy-edge-mm", "10"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto report = nlohmann::json::parse(std::ifstream(out / "report.json"));
  EXPECT_EQ(report["proxy_edge_mm"], 10.0);
  ASSERT_EQ(report["vessels"].size(), 3u);
  for (const auto& v : report["vessels"]) {
    const std::string name = v["name"];
    EXPECT_TRUE(fs::exists(out / (name + ".stl"))) << name;
    if (name == "aorta") {
      EXPECT_GT(v["proxy_vertices"].get<int>(), 0);
      EXPECT_EQ(v["proxy_refused"], "");
    } else {
      EXPECT_EQ(v["proxy_vertices"], 0) << name;
      EXPECT_NE(v["proxy_refused"].get<std::string>().find("thinner than the proxy's edge"), std::string::npos) << name;
      EXPECT_NE(r.err.find(name + ": solved on its own"), std::string::npos) << r.err;
    }
  }
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
void Cli::expect_deform_keeps(evar::geometry::MeshFormat format, const std::string& extension) {
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

TEST_F(Cli, ProjectPrintsPixelsAndWritesJson) {
  const auto dir = scratch("project");
  write_text(dir / "g.json", R"({"primary_angle_deg": 0, "secondary_angle_deg": 0, "source_to_detector_mm": 1200,
      "source_to_isocenter_mm": 800, "detector_size_px": [1000, 800], "pixel_spacing_mm": [0.3, 0.3]})");
  write_text(dir / "p.mrk.json", R"({"markups": [{"type": "Fiducial", "coordinateSystem": "LPS", "controlPoints": [
      {"label": "iso", "position": [0, 0, 0]}, {"label": "left", "position": [6, 0, 0]}]}]})");
  // CT origin 100 mm to the patient's right of the isocenter.
  write_text(dir / "t.json", R"({"matrix": [[1,0,0,-100],[0,1,0,0],[0,0,1,0],[0,0,0,1]]})");
  testing::internal::CaptureStdout();
  const int code = run_cli({"project", "--geometry", (dir / "g.json").string(), "--points", (dir / "p.mrk.json").string(),
                            "--out", (dir / "r.json").string()});
  const std::string table = testing::internal::GetCapturedStdout();
  ASSERT_EQ(code, 0);
  EXPECT_NE(table.find("499.50"), std::string::npos) << table;  // (cols − 1) / 2
  const auto r = nlohmann::json::parse(std::ifstream(dir / "r.json"));
  ASSERT_EQ(r["points"].size(), 2u);
  EXPECT_DOUBLE_EQ(r["points"][0]["pixel"][1].get<double>(), 399.5);
  // 6 mm at the isocenter, magnified 1.5, over 0.3 mm pixels: 30 px to the right.
  EXPECT_NEAR(r["points"][1]["pixel"][0].get<double>(), 529.5, 1e-9);
  EXPECT_EQ(r["points"][1]["where"], "on the detector");
  testing::internal::CaptureStdout();
  ASSERT_EQ(run_cli({"project", "--geometry", (dir / "g.json").string(), "--registration", (dir / "t.json").string(),
                     "--points", (dir / "p.mrk.json").string(), "--out", (dir / "r2.json").string()}),
            0);
  testing::internal::GetCapturedStdout();
  const auto r2 = nlohmann::json::parse(std::ifstream(dir / "r2.json"));
  EXPECT_NEAR(r2["points"][0]["pixel"][0].get<double>(), 499.5 - 100 * 1.5 / 0.3, 1e-9);
}

TEST_F(Cli, ProjectNamesABadGeometryField) {
  const auto dir = scratch("project_bad");
  write_text(dir / "g.json", R"({"primary_angle_deg": 0, "secondary_angle_deg": 0, "source_to_detector_mm": 700,
      "source_to_isocenter_mm": 800, "detector_size_px": [1000, 800], "pixel_spacing_mm": [0.3, 0.3]})");
  write_text(dir / "p.mrk.json", R"({"markups": [{"type": "Fiducial", "controlPoints": [{"position": [0, 0, 0]}]}]})");
  const auto run = evarnode({"project", "--geometry", (dir / "g.json").string(), "--points", (dir / "p.mrk.json").string()});
  EXPECT_EQ(run.code, 1);
  EXPECT_NE(run.err.find("g.json: source_to_isocenter_mm"), std::string::npos) << run.err;
}

TEST_F(Cli, ProjectReadsTheGeometryOfADicomFile) {
  const auto dir = scratch("project_dicom");
  evar::geometry::CArmView v;
  v.primary_angle_deg = 0;
  v.secondary_angle_deg = 0;
  v.source_to_detector_mm = 1200;
  v.source_to_isocenter_mm = 800;
  v.detector_cols = 100;
  v.detector_rows = 80;
  v.row_spacing_mm = v.col_spacing_mm = 0.3;
  evar::geometry::write_xa_dicom(dir / "view.img", v, {cv::Mat(80, 100, CV_16UC1, cv::Scalar(100))});
  write_text(dir / "p.mrk.json", R"({"markups": [{"type": "Fiducial", "controlPoints": [{"position": [0, 0, 0]}]}]})");
  testing::internal::CaptureStdout();
  const int code = run_cli({"project", "--geometry", (dir / "view.img").string(), "--points",
                            (dir / "p.mrk.json").string(), "--out", (dir / "r.json").string()});
  testing::internal::GetCapturedStdout();
  ASSERT_EQ(code, 0);
  const auto r = nlohmann::json::parse(std::ifstream(dir / "r.json"));
  EXPECT_DOUBLE_EQ(r["points"][0]["pixel"][0].get<double>(), 49.5);
}

namespace {
// Two rendered frames of a known wire, 30 degrees LAO and RAO, as PNG + geometry and DICOM.
struct TwoFrames {
  fs::path dir;
  evar::geometry::Polyline wire;
};
// The views the CLI tests render: 768² at 0.4 mm, SID 1200 mm, SOD 800 mm.
evar::geometry::CArmView test_view(double primary_deg) { return evar::test::detector_view(primary_deg, 0.0, 768, 0.4); }

TwoFrames write_two_frames(const fs::path& dir, double separation_deg = 60.0) {
  TwoFrames t{dir, evar::sim::iliac_guidewire()};
  for (int k = 0; k < 2; ++k) {
    const evar::geometry::CArmView v = test_view((k == 0 ? 0.5 : -0.5) * separation_deg);
    evar::sim::FluoroOptions o;
    o.seed = static_cast<std::uint64_t>(k + 1);
    const auto f = evar::sim::render_fluoro(evar::geometry::projection_matrix(v), v, {t.wire}, o);
    const std::string n = std::to_string(k + 1);
    cv::imwrite((dir / ("view" + n + ".png")).string(), f.image);
    evar::geometry::write_view_geometry(dir / ("view" + n + ".json"), v);
    evar::geometry::write_xa_dicom(dir / ("view" + n + ".dcm"), v, {f.image}, k == 1, 12);
  }
  return t;
}
}  // namespace

TEST_F(Cli, SegmentWritesTheCurveAndSaysWhenThereIsNone) {
  const auto dir = scratch("segment");
  write_two_frames(dir);
  ASSERT_EQ(evarnode({"segment", "--image", (dir / "view1.png").string(), "--geometry", (dir / "view1.json").string(),
                      "--out", (dir / "d.json").string(), "--overlay", (dir / "o.png").string()})
                .code,
            0);
  const auto j = nlohmann::json::parse(std::ifstream(dir / "d.json"));
  EXPECT_TRUE(j["found"].get<bool>());
  EXPECT_GT(j["points_px"].size(), 100u);
  EXPECT_NEAR(j["device_width_px"].get<double>(), 0.89 * 1.5 / 0.4, 1e-9);
  EXPECT_TRUE(fs::exists(dir / "o.png"));
  cv::imwrite((dir / "blank.png").string(), cv::Mat(200, 200, CV_16UC1, cv::Scalar(3000)));
  const auto none = evarnode({"segment", "--image", (dir / "blank.png").string(), "--out", (dir / "n.json").string()});
  EXPECT_EQ(none.code, 3);
  EXPECT_NE(none.err.find("no device found"), std::string::npos) << none.err;
  EXPECT_FALSE(nlohmann::json::parse(std::ifstream(dir / "n.json"))["found"].get<bool>());
  write_text(dir / "junk.png", "not an image");
  EXPECT_EQ(evarnode({"segment", "--image", (dir / "junk.png").string(), "--out", (dir / "x.json").string()}).code, 1);
}

TEST_F(Cli, ReconstructFromPngsAndFromDicomMatchesTheWire) {
  const auto dir = scratch("reconstruct");
  const auto t = write_two_frames(dir);
  for (const bool dicom : {false, true}) {
    std::vector<std::string> args{"reconstruct", "--out", (dir / "device.mrk.json").string(), "--report",
                                  (dir / "r.json").string()};
    for (const char* n : {"1", "2"}) {
      args.insert(args.end(), {"--image", (dir / (std::string("view") + n + (dicom ? ".dcm" : ".png"))).string()});
      if (!dicom) args.insert(args.end(), {"--geometry", (dir / (std::string("view") + n + ".json")).string()});
    }
    const auto run = evarnode(args);
    ASSERT_EQ(run.code, 0) << run.err;
    const auto curve = evar::geometry::read_curve(dir / "device.mrk.json", 2);
    double sum = 0.0;
    for (const auto& p : curve.points) sum += evar::geometry::project_onto(t.wire, p.position_lps).distance_mm;
    EXPECT_LT(sum / static_cast<double>(curve.points.size()), 1.0) << (dicom ? "DICOM" : "PNG");
    EXPECT_LT((curve.points.front().position_lps - t.wire.front()).norm(), 3.0);  // tip first
    const auto report = nlohmann::json::parse(std::ifstream(dir / "r.json"));
    EXPECT_NEAR(report["separation_deg"].get<double>(), 60.0, 1e-6);
  }
}

TEST_F(Cli, ReconstructRefusesViewsTooCloseTogether) {
  const auto dir = scratch("reconstruct_close");
  write_two_frames(dir, 12.0);
  const auto run = evarnode({"reconstruct", "--image", (dir / "view1.dcm").string(), "--image", (dir / "view2.dcm").string(),
                             "--out", (dir / "d.mrk.json").string(), "--report", (dir / "r.json").string()});
  EXPECT_EQ(run.code, 1);
  EXPECT_NE(run.err.find("degrees apart"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir / "d.mrk.json"));
  EXPECT_TRUE(nlohmann::json::parse(std::ifstream(dir / "r.json")).contains("error"));
}

// The whole chain on files: two simulated frames of the example's guidewire, registered to
// the C-arm with its sac at the isocenter → reconstruct (into CT LPS) → deform.
TEST_F(Cli, ReconstructedDeviceDrivesTheDeformation) {
  const auto dir = scratch("chain");
  evar::sim::ExampleSceneParams p;
  p.aorta_vertices = 2500;
  p.iliac_vertices = 1500;
  const auto example = evar::sim::make_example_scene(p);
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.block<3, 1>(0, 3) = -Eigen::Vector3d(0, 0, p.aneurysm_centre_z_mm);  // CT → C-arm: sac centre at the isocenter
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
  write_text(dir / "T.json", nlohmann::json{{"matrix", rows}}.dump());
  evar::geometry::Polyline wire;
  for (const auto& d : example.device) wire.push_back((T * d.homogeneous()).head<3>());
  for (int k = 0; k < 2; ++k) {
    const evar::geometry::CArmView v = test_view(k == 0 ? 35 : -35);
    evar::sim::FluoroOptions o;
    o.seed = static_cast<std::uint64_t>(k + 7);
    const auto f = evar::sim::render_fluoro(evar::geometry::projection_matrix(v), v, {wire}, o);
    evar::geometry::write_xa_dicom(dir / (k == 0 ? "v0.dcm" : "v1.dcm"), v, {f.image}, false, 12);
  }
  const auto rec = evarnode({"reconstruct", "--image", (dir / "v0.dcm").string(), "--image", (dir / "v1.dcm").string(),
                             "--registration", (dir / "T.json").string(), "--out", (dir / "device.mrk.json").string()});
  ASSERT_EQ(rec.code, 0) << rec.err;
  // In CT coordinates again, on the example's own device.
  const auto curve = evar::geometry::read_curve(dir / "device.mrk.json", 2);
  double sum = 0.0;
  for (const auto& q : curve.points) sum += evar::geometry::project_onto(example.device, q.position_lps).distance_mm;
  EXPECT_LT(sum / static_cast<double>(curve.points.size()), 1.0);
  const auto def = evarnode({"deform", "--scene", scene().string(), "--device", (dir / "device.mrk.json").string(), "--out",
                             (dir / "deformed").string(), "--no-preview"});
  ASSERT_EQ(def.code, 0) << def.err;
  const auto report = nlohmann::json::parse(std::ifstream(dir / "deformed" / "report.json"));
  int control_points = 0;
  for (const auto& v : report["vessels"]) control_points += v["control_points"].get<int>();
  EXPECT_GT(control_points, 0);
}

// The evaluation loop a research user runs: a synthetic patient, deform it, compare with
// its truth. The carrier's internal iliac ostium must end closer to its true position.
TEST_F(Cli, SimPatientFeedsDeformAndItsTruthIsComparable) {
  const auto out = scratch("sim_patient");
  ASSERT_EQ(evarnode({"sim", "patient", "--seed", "5", "--out", (out / "p").string(), "--aorta-vertices", "3000",
                      "--iliac-vertices", "1500"}).code, 0);
  for (const char* f : {"scene.json", "device.mrk.json", "patient.json", "truth/scene.json", "truth/landmarks.mrk.json"})
    EXPECT_TRUE(fs::exists(out / "p" / f)) << f;
  ASSERT_EQ(evarnode({"deform", "--scene", (out / "p/scene.json").string(), "--device", (out / "p/device.mrk.json").string(),
                      "--out", (out / "r").string(), "--no-preview"}).code, 0);
  const auto carrier = nlohmann::json::parse(std::ifstream(out / "p/patient.json"))["ground_truth"]["carrier"].get<std::string>();
  const std::string label = carrier == "iliac_left" ? "internal_iliac_left" : "internal_iliac_right";
  const auto at = [&](const fs::path& file) {
    for (const auto& m : evar::geometry::read_markups(file))
      for (const auto& p : m.points)
        if (p.label == label) return p.position_lps;
    ADD_FAILURE() << label << " not in " << file;
    return Eigen::Vector3d::Zero().eval();
  };
  const Eigen::Vector3d truth = at(out / "p/truth/landmarks.mrk.json");
  const double before = (at(out / "p/landmarks.mrk.json") - truth).norm();
  const double after = (at(out / "r/landmarks.mrk.json") - truth).norm();
  EXPECT_GT(before, 2.0);  // the device really moves it
  EXPECT_LT(after, 0.5 * before);
}

// `eval`, the paper's Table 1 on a simulated session with ground truth: the carrier's
// internal iliac ostium comes much closer, none gets worse, and the device the node
// reconstructed is measured against the true one in 3D.
TEST_F(Cli, EvalMeasuresTheOstiaBeforeAndAfterAndTheReconstructedDevice) {
  const auto out = scratch("eval");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "1", "--detector-px", "256", "--out", (out / "s1").string()}).code, 0);
  const auto r = evarnode({"eval", (out / "s1").string(), "--out", (out / "e").string()});
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* f : {"eval.json", "eval.md", "per_case.png", "distribution.png"}) EXPECT_TRUE(fs::exists(out / "e" / f)) << f;
  const auto j = nlohmann::json::parse(std::ifstream(out / "e" / "eval.json"));
  ASSERT_EQ(j["cases"].size(), 1u);
  const auto& c = j["cases"][0];
  const std::string carrier =
      nlohmann::json::parse(std::ifstream(out / "s1" / "patient" / "patient.json"))["ground_truth"]["carrier"];
  const std::string carrier_ostium = carrier == "iliac_left" ? "internal_iliac_left" : "internal_iliac_right";
  ASSERT_EQ(c["landmarks"].size(), 4u);  // two renal and two internal iliac ostia, each seen
  EXPECT_EQ(c["device_iliac"], carrier) << "the iliac the true device runs in";
  bool saw_carrier = false;
  for (const auto& l : c["landmarks"]) {
    const double before = l["initial_mm"], after = l["adapted_mm"];
    EXPECT_GT(l["frames"].get<int>(), 20) << l["label"];
    EXPECT_LT(after, before + 0.5) << l["label"] << " got worse";
    EXPECT_EQ(l["on_device_vessel"].get<bool>(), l["label"] == carrier_ostium) << l["label"];
    if (l["label"] == carrier_ostium) {
      saw_carrier = true;
      EXPECT_EQ(l["vessel"], carrier);
      EXPECT_GT(before, 1.0) << "the device does not move the carrier's ostium: nothing to measure";
      EXPECT_LT(after, 0.5 * before) << l["label"];
    }
  }
  EXPECT_TRUE(saw_carrier) << carrier_ostium;
  EXPECT_LT(j["summary"]["euclidean"]["adapted"]["mean_mm"].get<double>(),
            j["summary"]["euclidean"]["initial"]["mean_mm"].get<double>());
  // The paper's protocol (its Table 1): the ostia on the iliac carrying the device.
  const auto& paper = j["summary"]["device_iliac_ostia"]["euclidean"];
  EXPECT_EQ(paper["initial"]["n"], 1);
  EXPECT_LT(paper["adapted"]["mean_mm"].get<double>(), 0.5 * paper["initial"]["mean_mm"].get<double>());
  // The reconstruction from two 256 x 256 views (1.2 mm pixels, 0.8 mm at the isocenter):
  // sub-pixel curves put the device within half an isocenter pixel on average (measured
  // 0.15 mm), its worst point (the tip, where the two views' ends differ) within two.
  const auto& d = j["summary"]["device_reconstruction"];
  EXPECT_GE(d["models"].get<int>(), 1);
  EXPECT_EQ(c["device_errors"].size(), d["models"].get<std::size_t>());
  EXPECT_GT(d["mean_mm"].get<double>(), 0.0);
  EXPECT_LT(d["mean_mm"].get<double>(), 0.4);
  EXPECT_LT(d["worst_point_mm"].get<double>(), 1.6);
  // How much of the wire it spans: the part in both views, less than the whole wire (which
  // runs on to the access outside the field of view) and more than a sliver.
  for (const auto& e : c["device_errors"]) {
    EXPECT_GT(e["covered_mm"].get<double>(), 50.0);
    EXPECT_LT(e["covered_mm"].get<double>(), e["true_length_mm"].get<double>());
  }
  // Both devices, for Slicer or `deform --device`: the reconstructed one first.
  const auto devices = nlohmann::json::parse(std::ifstream(out / "e" / "devices" / "01-s1.mrk.json"));
  ASSERT_EQ(devices["markups"].size(), 2u);
  EXPECT_EQ(devices["markups"][0]["name"], "reconstructed device");
  EXPECT_EQ(devices["markups"][0]["controlPoints"].size(), c["model"]["device_points"].get<std::size_t>());
  EXPECT_EQ(devices["markups"][1]["name"], "true device");
  std::ifstream md(out / "e" / "eval.md");
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("Reconstructed device against the true device"), std::string::npos) << text;
}

// At the paper's difficulty the registration given to the node is off by a residual: eval
// still measures the reconstructed device against the true one in the node's frame (a
// device compared across the residual would be millimetres off), says which physics and
// difficulty each case is, and reports each physics on its own.
TEST_F(Cli, EvalOfAPaperDifficultySessionReportsItsPhysicsAndTheResidual) {
  const auto out = scratch("eval_paper");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "3", "--difficulty", "paper", "--physics", "conforming", "--detector-px",
                      "256", "--fluoro-seconds", "1", "--out", (out / "s").string()})
                .code,
            0);
  const auto r = evarnode({"eval", (out / "s").string(), "--out", (out / "e").string(), "--no-progress"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(std::ifstream(out / "e" / "eval.json"));
  const auto& c = j["cases"][0];
  EXPECT_EQ(c["physics"], "conforming");
  EXPECT_EQ(c["difficulty"], "paper");
  EXPECT_GT(c["registration_residual_deg"].get<double>(), 0.1);
  EXPECT_LT(c["registration_residual_deg"].get<double>(), 5.0 * std::sqrt(3.0));
  ASSERT_TRUE(j["summary"]["by_physics"].contains("conforming physics, paper difficulty")) << j["summary"].dump();
  EXPECT_LT(j["summary"]["device_reconstruction"]["mean_mm"].get<double>(), 0.4);
  for (const auto& l : c["landmarks"])
    if (l["label"].get<std::string>().rfind("renal", 0) == 0) {
      EXPECT_LT(l["initial_mm"].get<double>(), 3.0) << l["label"];
    }
  std::ifstream md(out / "e" / "eval.md");
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("## conforming physics, paper difficulty"), std::string::npos) << text;
}

// A recording without ground truth cannot be evaluated: said with the file and the field.
TEST_F(Cli, EvalOfASessionWithoutGroundTruthNamesTheField) {
  const auto out = scratch("eval_no_truth");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "2", "--detector-px", "256", "--out", (out / "s").string()}).code, 0);
  auto j = nlohmann::json::parse(std::ifstream(out / "s" / "session.json"));
  j.erase("ground_truth");
  std::ofstream(out / "s" / "session.json") << j.dump(2);
  const auto r = evarnode({"eval", (out / "s").string(), "--out", (out / "e").string()});
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("session.json"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("ground_truth"), std::string::npos) << r.err;
}

// Seed 7's tortuous iliac, pushed into a tight bend, was refused at first and then
// made with an extra pass on the meshes; both came from the inside test's repeated hits
// (since fixed). Its truth holds the device in the distorted vessels, checked here
// on the written files: every device point inside a truth mesh or within Δd of a wall.
TEST_F(Cli, SimPatientSeed7HoldsTheDeviceInItsTruth) {
  const auto out = scratch("sim_patient_seed7");
  const auto r = evarnode({"sim", "patient", "--seed", "7", "--out", out.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto truth = evar::geometry::load_scene(out / "truth" / "scene.json");
  std::vector<evar::geometry::RayCaster> casters;
  for (const auto& v : truth.vessels) casters.emplace_back(v.mesh.mesh);
  const auto device = evar::geometry::read_curve(out / "truth" / "device.mrk.json").points;
  ASSERT_GT(device.size(), 50u);
  for (const auto& d : device) {
    bool held = false;
    for (std::size_t i = 0; i < casters.size() && !held; ++i)
      held = casters[i].contains(d.position_lps) ||
             evar::geometry::closest_point_on_mesh(truth.vessels[i].mesh.mesh, d.position_lps).distance_mm <=
                 truth.device_thickness_mm;
    EXPECT_TRUE(held) << d.position_lps.transpose();
  }
  const auto j = nlohmann::json::parse(std::ifstream(out / "patient.json"));
  EXPECT_GE(j["ground_truth"]["mesh_passes"].get<int>(), 0);
}

// A simulated intervention, replayed through the acquisition interfaces: every frame
// arrives, none while the C-arm moves, in the three views the session was made in.
TEST_F(Cli, SimSessionThenReplayDeliversEveryFrameInItsViews) {
  const auto out = scratch("sim_session");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "2", "--out", (out / "s").string(), "--detector-px", "96",
                      "--fluoro-seconds", "0.2", "--no-progress"}).code, 0);
  ASSERT_EQ(evarnode({"replay", (out / "s").string(), "--fast", "--loop", "2", "--no-progress", "--report",
                      (out / "r.json").string()}).code, 0);
  const auto r = nlohmann::json::parse(std::ifstream(out / "r.json"));
  // 3 runs of 3 fluoroscopy frames and 12 DSA frames (4 fps for 3 s), twice.
  EXPECT_EQ(r["frames"], 2 * (9 + 12));
  EXPECT_EQ(r["dropped"], 0);
  EXPECT_EQ(r["frames_while_moving"], 0);
  EXPECT_GT(r["carm_moving_states"].get<int>(), 0);
  EXPECT_EQ(r["frames_per_view"].size(), 3u);
  EXPECT_EQ(r["error"], "");
}

TEST_F(Cli, ExportWritesASlicerSequenceOfEveryFrameAndNothingWhenAFrameDoesNotFit) {
  const auto out = scratch("export");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "2", "--out", (out / "s").string(), "--detector-px", "64",
                      "--fluoro-seconds", "0.2", "--no-progress"}).code, 0);
  const auto r = evarnode({"export", (out / "s").string(), "--out", (out / "run.seq.mha").string(), "--no-progress"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("wrote " + (out / "run.seq.mha").string() + ": 21 frames of 64 x 64"), std::string::npos) << r.err;
  // 9 fluoroscopy and 12 DSA frames, each 64 x 64 x 2 bytes after the header.
  std::ifstream in(out / "run.seq.mha", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  const auto data = bytes.find("ElementDataFile = LOCAL\n");
  ASSERT_NE(data, std::string::npos);
  EXPECT_NE(bytes.find("DimSize = 64 64 21\n"), std::string::npos);
  EXPECT_EQ(bytes.size() - data - std::string("ElementDataFile = LOCAL\n").size(), 21u * 64u * 64u * 2u);
  EXPECT_NE(bytes.find("Seq_Frame0020_Source = dsa\n"), std::string::npos);

  // A frame of another size: refused by name, and no sequence (nor a partial one) is left.
  cv::imwrite((out / "s" / "frames" / "000005.png").string(), cv::Mat(32, 64, CV_16UC1, cv::Scalar(100)));
  const auto bad = evarnode({"export", (out / "s").string(), "--out", (out / "bad.seq.mha").string(), "--no-progress"});
  EXPECT_EQ(bad.code, 1);
  EXPECT_NE(bad.err.find("000005.png: 64 x 32 pixels, but the detector is 64 x 64"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(out / "bad.seq.mha"));
  EXPECT_FALSE(fs::exists(out / "bad.seq.mha.partial"));
  // A name Slicer would not recognise is written, with a warning saying so.
  const auto plain = evarnode({"export", (out / "s").string(), "--out", (out / "run.mha").string(), "--no-progress"});
  EXPECT_EQ(plain.code, 1);  // the bad frame is still there
  EXPECT_NE(plain.err.find("recognises sequence metafiles by the name *.seq.mha"), std::string::npos) << plain.err;
}

TEST_F(Cli, ReplayOfACorruptSessionNamesTheFileAndLine) {
  const auto out = scratch("replay_corrupt");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "2", "--out", out.string(), "--detector-px", "64", "--fluoro-seconds", "0.1",
                      "--no-progress"}).code, 0);
  std::ofstream(out / "carm.csv", std::ios::app) << "12,0,0,1200,80x0,0,0,0,1,0\n";
  const auto r = evarnode({"replay", out.string(), "--fast", "--no-progress"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("carm.csv:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("sod_mm: '80x0' is not a number"), std::string::npos) << r.err;
}

// `export --out SESSION/carm.csv` overwrote the session's own C-arm stream with the sequence.
TEST_F(Cli, ExportRefusesAnOutputInsideTheSession) {
  const auto out = scratch("export_inside");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "2", "--out", (out / "s").string(), "--detector-px", "64",
                      "--fluoro-seconds", "0.1", "--no-progress"}).code, 0);
  std::ifstream in(out / "s" / "carm.csv", std::ios::binary);
  const std::string carm((std::istreambuf_iterator<char>(in)), {});
  const auto r = evarnode({"export", (out / "s").string(), "--out", (out / "s" / "carm.csv").string(), "--no-progress"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("carm.csv: is inside the session directory"), std::string::npos) << r.err;
  std::ifstream again(out / "s" / "carm.csv", std::ios::binary);
  EXPECT_EQ(std::string((std::istreambuf_iterator<char>(again)), {}), carm);
  EXPECT_EQ(evarnode({"export", (out / "s").string(), "--out", (out / "s" / "frames" / "run.seq.mha").string(),
                      "--no-progress"}).code, 1);
  EXPECT_FALSE(fs::exists(out / "s" / "frames" / "run.seq.mha"));
}

// `run --speed` had no lower bound: at 1e-12 the wait for a frame overflowed the clock.
TEST_F(Cli, RunTakesTheReplaysSpeedRange) {
  const auto out = scratch("run_speed");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "2", "--out", (out / "s").string(), "--detector-px", "64",
                      "--fluoro-seconds", "0.1", "--no-progress"}).code, 0);
  for (const std::string speed : {"1e-12", "0.001", "5000"})
    EXPECT_EQ(evarnode({"run", "--replay", (out / "s").string(), "--speed", speed, "--out", (out / "run").string(),
                        "--no-video", "--no-igtl", "--seconds", "1", "--no-progress"}).code, 2)
        << speed;
}

// A recorder killed mid-recording (here by SIGKILL) leaves frames and its journal; `record
// --recover` makes them a session `replay` takes.
TEST_F(Cli, RecordRecoverMakesASessionOfAKilledRecording) {
  const auto out = scratch("record_recover");
  evar::session::Session original;
  original.scene = "scene.json";
  original.detector = {32, 24, 0.3, 0.3};
  const auto images = evar::test::add_ramp_frames(original, 6, 50'000'000LL, {3000, 11, 7, 2});
  for (int k = 0; k < 3; ++k) {
    evar::session::CArmSample c;
    c.timestamp_ns = 990'000'000LL + k * 100'000'000LL;
    c.primary_deg = 15.0 * k;
    c.sid_mm = 1200;
    c.sod_mm = 800;
    c.fluoro_on = true;
    original.carm.push_back(c);
  }
  evar::session::write_session(out / "original", original, images);
  evar::session::RecorderOptions o;
  o.out = out / "recorded";
  o.scene = scene();
  o.pixel_spacing_mm = 0.2;
  const int status = evar::test::record_then_kill(o, evar::session::read_session(out / "original"));
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "child status " << status;

  const auto r = evarnode({"record", "--recover", o.out.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("6 frames and 3 C-arm states recovered"), std::string::npos) << r.err;
  const auto replayed = evarnode({"replay", o.out.string(), "--fast", "--no-progress"});
  EXPECT_EQ(replayed.code, 0) << replayed.err;
  EXPECT_NE(replayed.err.find("6 frames (0 dropped) and 3 C-arm states"), std::string::npos) << replayed.err;

  const auto again = evarnode({"record", "--recover", o.out.string()});
  EXPECT_EQ(again.code, 1);
  EXPECT_NE(again.err.find("a finished session"), std::string::npos) << again.err;
  // --recover stands alone; a recording needs its options.
  EXPECT_EQ(evarnode({"record", "--recover", o.out.string(), "--carm", "serial:/dev/null"}).code, 2);
  const auto missing = evarnode({"record", "--scene", scene().string(), "--out", (out / "x").string()});
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.err.find("--carm"), std::string::npos) << missing.err;
}

// Each side may be up to 16384 px, but no session holds frames of more than 8192 x 8192 in
// all: a size its frames could never be written at is refused before anything is opened.
TEST_F(Cli, RecordRefusesAFrameSizeNoSessionCanHold) {
  const auto out = scratch("record_big");
  const auto args = [&](const char* w, const char* h) {
    return std::vector<std::string>{"record", "--camera", "NONE", "--carm", "serial:/dev/null", "--scene",
                                    scene().string(), "--registration", scene().string(), "--pixel-spacing", "0.3",
                                    "--out", (out / "big").string(), "--width", w, "--height", h};
  };
  const auto big = evarnode(args("16384", "8193"));
  EXPECT_EQ(big.code, 2);
  EXPECT_NE(big.err.find("16384 x 8193 pixels; a session's frames hold at most 67108864 in all"), std::string::npos)
      << big.err;
  EXPECT_FALSE(fs::exists(out / "big"));
  // 16384 x 4096 is within the limit: it gets past the options (and fails on the camera).
  const auto wide = evarnode(args("16384", "4096"));
  EXPECT_EQ(wide.code, 1) << wide.err;
}
