// scene.json: loading a patient scene with its meshes, centerlines and landmarks, paths
// relative to the scene file, and every rule load_scene enforces.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

#include <nlohmann/json.hpp>

#include "evar/base/input_error.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/scene.hpp"

namespace fs = std::filesystem;
using evar::base::InputError;
using evar::geometry::load_scene;
using evar::geometry::Markup;
using evar::geometry::MeshFormat;
using evar::geometry::Scene;
using evar::geometry::SceneManifest;
using evar::geometry::to_string;
using evar::geometry::TriangleMesh;
using evar::geometry::VesselKind;
using evar::geometry::write_markups;
using evar::geometry::write_mesh;
using evar::geometry::write_scene_manifest;
using nlohmann::json;
using testing::HasSubstr;

namespace {

fs::path test_dir() {
  const auto* info = testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::path(testing::TempDir()) / ("evar_geometry_scene_" + std::to_string(::getpid())) /
                       (std::string(info->test_suite_name()) + "." + info->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// A closed tetrahedron, shifted so each vessel's mesh is recognisable.
TriangleMesh tetrahedron(double shift) {
  TriangleMesh m;
  m.V.resize(4, 3);
  m.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  m.V.col(2).array() += shift;
  m.F.resize(4, 3);
  m.F << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  return m;
}

Markup curve(double z0) {
  return {"Curve", "centerline", {{"C-1", {0, 0, z0}}, {"C-2", {0, 0, z0 - 10}}, {"C-3", {1, 0, z0 - 20}}}};
}

// A complete scene in dir/patient (meshes in a sub-folder, to exercise relative paths).
fs::path make_scene(const fs::path& dir) {
  const fs::path root = dir / "patient";
  fs::create_directories(root / "meshes");
  write_mesh(root / "meshes" / "aorta.stl", tetrahedron(100), MeshFormat::StlBinary);
  write_mesh(root / "meshes" / "iliac_r.ply", tetrahedron(50), MeshFormat::PlyBinary);
  write_markups(root / "aorta.centerline.mrk.json", {curve(100)});
  write_markups(root / "iliac_r.centerline.mrk.json", {curve(50)});
  write_markups(root / "landmarks.mrk.json",
                {Markup{"Fiducial", "L", {{"renal_left", {1, 2, 3}}, {"bifurcation", {4, 5, 6}}}}});
  SceneManifest manifest;
  manifest.vessels = {{"aorta", "aorta", "meshes/aorta.stl", "aorta.centerline.mrk.json"},
                      {"iliac_right", "iliac", "meshes/iliac_r.ply", "iliac_r.centerline.mrk.json"}};
  manifest.landmarks = "landmarks.mrk.json";
  manifest.device_thickness_mm = 0.9;
  write_scene_manifest(root / "scene.json", manifest);
  return root / "scene.json";
}

json read_json(const fs::path& file) {
  std::ifstream in(file);
  return json::parse(in);
}

void write_json(const fs::path& file, const json& j) { std::ofstream(file) << j.dump(2); }

std::string scene_error(const fs::path& file) {
  try {
    load_scene(file);
  } catch (const evar::base::InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "load_scene(" << file << ") did not throw evar::base::InputError";
  return {};
}

// Edits a valid scene.json and returns load_scene's error message.
std::string error_after_edit(const fs::path& dir, const std::function<void(json&)>& edit) {
  const fs::path file = make_scene(dir);
  json j = read_json(file);
  edit(j);
  write_json(file, j);
  return scene_error(file);
}

}  // namespace

TEST(LoadScene, LoadsVesselsCenterlinesLandmarksAndThickness) {
  const fs::path file = make_scene(test_dir());
  const Scene scene = load_scene(file);

  EXPECT_EQ(scene.file, file);
  EXPECT_DOUBLE_EQ(scene.device_thickness_mm, 0.9);
  ASSERT_EQ(scene.vessels.size(), 2u);

  const auto& aorta = scene.vessels[0];
  EXPECT_EQ(aorta.name, "aorta");
  EXPECT_EQ(aorta.kind, VesselKind::Aorta);
  EXPECT_EQ(aorta.mesh_path, file.parent_path() / "meshes/aorta.stl");
  EXPECT_EQ(aorta.mesh.format, MeshFormat::StlBinary);
  EXPECT_EQ(aorta.mesh.mesh.F.rows(), 4);
  EXPECT_EQ(aorta.mesh.mesh.V.col(2).minCoeff(), 100.0);
  ASSERT_EQ(aorta.centerline.size(), 3u);
  EXPECT_EQ(aorta.centerline[0], Eigen::Vector3d(0, 0, 100));
  EXPECT_EQ(aorta.centerline[2], Eigen::Vector3d(1, 0, 80));

  const auto& iliac = scene.vessels[1];
  EXPECT_EQ(iliac.name, "iliac_right");
  EXPECT_EQ(iliac.kind, VesselKind::Iliac);
  EXPECT_EQ(iliac.mesh.format, MeshFormat::PlyBinary);
  EXPECT_EQ(iliac.mesh.mesh.V, tetrahedron(50).V);  // PLY keeps vertex order exactly
  EXPECT_EQ(iliac.centerline[0], Eigen::Vector3d(0, 0, 50));

  EXPECT_EQ(scene.landmarks_path, file.parent_path() / "landmarks.mrk.json");
  ASSERT_EQ(scene.landmarks.size(), 2u);
  EXPECT_EQ(scene.landmarks[1].label, "bifurcation");
  EXPECT_EQ(scene.landmarks[1].position_lps, Eigen::Vector3d(4, 5, 6));
}

TEST(LoadScene, WorksFromAnotherWorkingDirectoryAndWithoutLandmarks) {
  const fs::path dir = test_dir();
  const fs::path file = make_scene(dir);
  json j = read_json(file);
  j.erase("landmarks");
  write_json(file, j);

  const fs::path previous = fs::current_path();
  fs::current_path(dir);  // the scene is found through a relative path from elsewhere
  Scene scene;
  EXPECT_NO_THROW(scene = load_scene(fs::path("patient") / "scene.json"));
  fs::current_path(previous);
  EXPECT_EQ(scene.vessels.size(), 2u);
  EXPECT_TRUE(scene.landmarks_path.empty());
  EXPECT_TRUE(scene.landmarks.empty());
}

TEST(WriteSceneManifest, WritesTheDocumentedFields) {
  const fs::path file = make_scene(test_dir());
  const json j = read_json(file);
  EXPECT_EQ(j["format"], "evarnode-scene");
  EXPECT_EQ(j["version"], 1);
  EXPECT_EQ(j["coordinate_system"], "LPS");
  EXPECT_EQ(j["units"], "mm");
  EXPECT_EQ(j["vessels"][1]["kind"], "iliac");
  EXPECT_EQ(j["vessels"][1]["mesh"], "meshes/iliac_r.ply");
  EXPECT_EQ(j["landmarks"], "landmarks.mrk.json");
  EXPECT_EQ(j["device_thickness_mm"], 0.9);
}

TEST(WriteSceneManifest, RefusesAManifestLoadSceneWouldReject) {
  SceneManifest two_aortas;
  two_aortas.vessels = {{"a", "aorta", "a.stl", "a.mrk.json"}, {"b", "aorta", "b.stl", "b.mrk.json"}};
  EXPECT_THROW(write_scene_manifest(test_dir() / "scene.json", two_aortas), std::invalid_argument);
  SceneManifest bad_kind;
  bad_kind.vessels = {{"a", "aorta", "a.stl", "a.mrk.json"}, {"b", "vein", "b.stl", "b.mrk.json"}};
  EXPECT_THROW(write_scene_manifest(test_dir() / "scene.json", bad_kind), std::invalid_argument);
}

TEST(LoadScene, RefusesSceneFieldsThatBreakTheRules) {
  struct Case {
    const char* what;
    std::function<void(json&)> edit;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {"format", [](json& j) { j["format"] = "other"; }, "format: expected \"evarnode-scene\""},
      {"version", [](json& j) { j["version"] = 2; }, "version: unsupported version 2"},
      {"version type", [](json& j) { j["version"] = "1"; }, "version: unsupported version \"1\""},
      {"ras", [](json& j) { j["coordinate_system"] = "RAS"; }, "coordinate_system: expected \"LPS\", found \"RAS\""},
      {"units", [](json& j) { j["units"] = "cm"; }, "units: expected \"mm\""},
      {"no units", [](json& j) { j.erase("units"); }, "units: missing"},
      {"no vessels", [](json& j) { j["vessels"] = json::array(); }, "vessels: the scene has no vessels"},
      {"vessels type", [](json& j) { j["vessels"] = "aorta"; }, "vessels: expected an array, found string"},
      {"no aorta", [](json& j) { j["vessels"][0]["kind"] = "iliac"; }, "vessels: no vessel of kind \"aorta\""},
      {"two aortas", [](json& j) { j["vessels"][1]["kind"] = "aorta"; }, "vessels[1].kind: a second vessel of kind \"aorta\""},
      {"kind", [](json& j) { j["vessels"][1]["kind"] = "renal"; }, "vessels[1].kind: unknown vessel kind \"renal\""},
      {"duplicate name", [](json& j) { j["vessels"][1]["name"] = "aorta"; }, "vessels[1].name: another vessel is already named \"aorta\""},
      {"name type", [](json& j) { j["vessels"][0]["name"] = 7; }, "vessels[0].name: expected a string, found number"},
      {"no mesh", [](json& j) { j["vessels"][1].erase("mesh"); }, "vessels[1].mesh: missing"},
      {"thickness", [](json& j) { j["device_thickness_mm"] = -0.1; }, "device_thickness_mm: must be a number from 0 to 15 (mm)"},
      {"thick", [](json& j) { j["device_thickness_mm"] = 1e300; }, "device_thickness_mm: must be a number from 0 to 15 (mm)"},
      {"thickness type", [](json& j) { j["device_thickness_mm"] = "0.9"; }, "device_thickness_mm: expected a number, found string"},
      {"missing mesh file", [](json& j) { j["vessels"][1]["mesh"] = "meshes/gone.stl"; },
       "vessels[1].mesh: "},
      {"landmarks type", [](json& j) { j["landmarks"] = 3; }, "landmarks: expected a string, found number"},
  };
  const fs::path dir = test_dir();
  for (std::size_t i = 0; i < cases.size(); ++i) {
    SCOPED_TRACE(cases[i].what);
    const std::string msg = error_after_edit(dir / std::to_string(i), cases[i].edit);
    EXPECT_THAT(msg, HasSubstr("scene.json: " + cases[i].expected));
  }
}

TEST(LoadScene, ErrorsInNamedFilesNameBothTheSceneFieldAndTheFile) {
  const fs::path dir = test_dir();
  {
    const std::string msg = error_after_edit(dir / "a", [](json& j) { j["vessels"][1]["mesh"] = "meshes/gone.stl"; });
    EXPECT_THAT(msg, HasSubstr("vessels[1].mesh: "));
    EXPECT_THAT(msg, HasSubstr("gone.stl: file does not exist"));
  }
  {
    // A mesh with a fin (an edge shared by three faces) fails validation by name.
    const fs::path file = make_scene(dir / "b");
    TriangleMesh fin = tetrahedron(100);
    fin.V.conservativeResize(5, 3);
    fin.V.row(4) << 5, 5, 5;
    fin.F.conservativeResize(5, 3);
    fin.F.row(4) << 0, 1, 4;
    write_mesh(file.parent_path() / "meshes" / "aorta.stl", fin, MeshFormat::StlBinary);
    const std::string msg = scene_error(file);
    EXPECT_THAT(msg, HasSubstr("scene.json: vessels[0].mesh: "));
    EXPECT_THAT(msg, HasSubstr("aorta.stl: non-manifold edge"));
  }
  {
    const fs::path file = make_scene(dir / "c");
    write_markups(file.parent_path() / "iliac_r.centerline.mrk.json",
                  {Markup{"Curve", "short", {{"C-1", {0, 0, 0}}}}});
    const std::string msg = scene_error(file);
    EXPECT_THAT(msg, HasSubstr("scene.json: vessels[1].centerline: "));
    EXPECT_THAT(msg, HasSubstr("iliac_r.centerline.mrk.json: markups[0].controlPoints: Curve 'short' has 1"));
  }
  {
    const fs::path file = make_scene(dir / "d");
    write_markups(file.parent_path() / "landmarks.mrk.json", {curve(0)});
    const std::string msg = scene_error(file);
    EXPECT_THAT(msg, HasSubstr("scene.json: landmarks: "));
    EXPECT_THAT(msg, HasSubstr("no \"Fiducial\" control points"));
  }
  {
    const fs::path file = dir / "garbage" / "scene.json";
    fs::create_directories(file.parent_path());
    std::ofstream(file) << "{\"format\": \"evarnode-scene\", ";
    EXPECT_THAT(scene_error(file), HasSubstr("scene.json: invalid JSON"));
  }
}

TEST(VesselKindName, MatchesTheSceneFileSpelling) {
  EXPECT_STREQ(to_string(VesselKind::Aorta), "aorta");
  EXPECT_STREQ(to_string(VesselKind::Iliac), "iliac");
}

TEST(CopyScene, CarriesEveryFileUnderUniqueNamesAndNeverOverwrites) {
  const fs::path dir = test_dir();
  const fs::path file = make_scene(dir);
  json j = read_json(file);
  // Two vessel names that make the same file name once cleaned ("iliac right" and "iliac/right").
  j["vessels"][1]["name"] = "iliac right";
  j["vessels"].push_back(j["vessels"][1]);
  j["vessels"][2]["name"] = "iliac/right";
  // Its own surface and centerline (two vessels may not share one), under the same file
  // names in another folder.
  fs::create_directories(file.parent_path() / "other");
  write_mesh(file.parent_path() / "other" / "iliac_r.ply", tetrahedron(30), MeshFormat::PlyBinary);
  write_markups(file.parent_path() / "other" / "iliac_r.centerline.mrk.json", {curve(30)});
  j["vessels"][2]["mesh"] = "other/iliac_r.ply";
  j["vessels"][2]["centerline"] = "other/iliac_r.centerline.mrk.json";
  // A proxy file (deform's cache; its bytes are not read here) goes along; one named but
  // missing is dropped (deform makes the proxy anew).
  std::ofstream(file.parent_path() / "aorta.proxy") << "proxy bytes";
  j["vessels"][0]["proxy"] = "aorta.proxy";
  j["vessels"][1]["proxy"] = "gone.proxy";
  write_json(file, j);
  const Scene original = load_scene(file);
  EXPECT_EQ(original.vessels[0].proxy_path, file.parent_path() / "aorta.proxy");
  EXPECT_TRUE(original.vessels[2].proxy_path.empty());

  const fs::path copy = copy_scene(original, dir / "copy");
  const Scene back = load_scene(copy);
  ASSERT_EQ(back.vessels.size(), 3u);
  EXPECT_NE(back.vessels[1].mesh_path, back.vessels[2].mesh_path);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(back.vessels[i].name, original.vessels[i].name);
    EXPECT_EQ(back.vessels[i].mesh.mesh.V, original.vessels[i].mesh.mesh.V);
    EXPECT_EQ(back.vessels[i].centerline, original.vessels[i].centerline);
  }
  EXPECT_EQ(back.landmarks.size(), original.landmarks.size());
  EXPECT_DOUBLE_EQ(back.device_thickness_mm, original.device_thickness_mm);
  ASSERT_FALSE(back.vessels[0].proxy_path.empty());
  EXPECT_EQ(back.vessels[0].proxy_path.parent_path(), dir / "copy");
  EXPECT_TRUE(fs::exists(back.vessels[0].proxy_path));
  EXPECT_TRUE(back.vessels[1].proxy_path.empty());
  // A second copy into the same place would overwrite: refused.
  EXPECT_THROW(copy_scene(original, dir / "copy"), fs::filesystem_error);
}

namespace {

// The tetrahedron as 3D Slicer before 4.11 saved it: RAS (x and y negated) with nothing in
// the file to say so.
void write_untagged_ras_obj(const fs::path& file, const TriangleMesh& lps) {
  std::ofstream out(file);
  for (Eigen::Index k = 0; k < lps.V.rows(); ++k)
    out << "v " << -lps.V(k, 0) << ' ' << -lps.V(k, 1) << ' ' << lps.V(k, 2) << '\n';
  for (Eigen::Index f = 0; f < lps.F.rows(); ++f)
    out << "f " << lps.F(f, 0) + 1 << ' ' << lps.F(f, 1) + 1 << ' ' << lps.F(f, 2) + 1 << '\n';
}

// make_scene's scene with its aorta replaced by an untagged RAS OBJ.
fs::path scene_with_untagged_ras_aorta(const fs::path& dir) {
  const fs::path file = make_scene(dir);
  write_untagged_ras_obj(file.parent_path() / "meshes" / "aorta.obj", tetrahedron(100));
  json j = read_json(file);
  j["vessels"][0]["mesh"] = "meshes/aorta.obj";
  write_json(file, j);
  return file;
}

}  // namespace

TEST(LoadScene, AnUntaggedMeshIsReadInTheCoordinateSystemTheSceneDeclaresForIt) {
  const fs::path dir = test_dir();
  const fs::path file = scene_with_untagged_ras_aorta(dir / "declared");
  // Without the declaration the file is LPS, as Slicer reads it: turned about the long axis.
  const Scene as_is = load_scene(file);
  EXPECT_EQ(as_is.vessels[0].mesh.space, evar::geometry::MeshSpace::Undeclared);
  EXPECT_GT((as_is.vessels[0].mesh.mesh.V - tetrahedron(100).V).cwiseAbs().maxCoeff(), 0.5);

  json j = read_json(file);
  j["vessels"][0]["mesh_coordinate_system"] = "RAS";
  write_json(file, j);
  const Scene scene = load_scene(file);
  EXPECT_EQ(scene.vessels[0].mesh.mesh.V, tetrahedron(100).V);
  // Written back in RAS, now saying so; the other vessel is untouched.
  EXPECT_EQ(scene.vessels[0].mesh.space, evar::geometry::MeshSpace::Ras);
  EXPECT_EQ(scene.vessels[0].declared_mesh_space, evar::geometry::MeshSpace::Ras);
  EXPECT_EQ(scene.vessels[1].mesh.mesh.V, tetrahedron(50).V);
  EXPECT_EQ(scene.vessels[1].declared_mesh_space, evar::geometry::MeshSpace::Undeclared);

  // A recorded session's copy of the scene keeps the declaration its untagged file needs.
  const Scene copied = load_scene(copy_scene(scene, dir / "copy"));
  EXPECT_EQ(copied.vessels[0].mesh.mesh.V, tetrahedron(100).V);
  EXPECT_EQ(copied.vessels[0].declared_mesh_space, evar::geometry::MeshSpace::Ras);
}

TEST(LoadScene, AMeshCoordinateSystemThatContradictsTheFileOrIsUnknownIsRefusedByField) {
  const fs::path dir = test_dir();
  // The STL make_scene writes says SPACE=LPS in its header.
  EXPECT_THAT(error_after_edit(dir / "contradicts", [](json& j) { j["vessels"][0]["mesh_coordinate_system"] = "RAS"; }),
              testing::AllOf(HasSubstr("scene.json: vessels[0].mesh_coordinate_system: is \"RAS\", but "),
                             HasSubstr("aorta.stl declares SPACE=LPS in its header")));
  // Saying what the file says is fine.
  {
    const fs::path file = make_scene(dir / "agrees");
    const auto as_is = load_scene(file).vessels[0].mesh.mesh.V;  // welded: STL's own vertex order
    json j = read_json(file);
    j["vessels"][0]["mesh_coordinate_system"] = "LPS";
    write_json(file, j);
    EXPECT_EQ(load_scene(file).vessels[0].mesh.mesh.V, as_is);
  }
  EXPECT_THAT(error_after_edit(dir / "unknown", [](json& j) { j["vessels"][1]["mesh_coordinate_system"] = "ras"; }),
              HasSubstr("scene.json: vessels[1].mesh_coordinate_system: unknown coordinate system \"ras\""));
  // null says nothing, as for "landmarks".
  {
    const fs::path file = make_scene(dir / "null");
    json j = read_json(file);
    j["vessels"][0]["mesh_coordinate_system"] = nullptr;
    write_json(file, j);
    EXPECT_EQ(load_scene(file).vessels[0].declared_mesh_space, evar::geometry::MeshSpace::Undeclared);
  }
  EXPECT_THAT(error_after_edit(dir / "type", [](json& j) { j["vessels"][1]["mesh_coordinate_system"] = 1; }),
              HasSubstr("scene.json: vessels[1].mesh_coordinate_system: expected a string, found number"));
  SceneManifest bad_space;
  bad_space.vessels = {{"a", "aorta", "a.stl", "a.mrk.json", "XYZ"}};
  EXPECT_THROW(write_scene_manifest(dir / "scene.json", bad_space), std::invalid_argument);
}

// The optional "pelvis": the pelvis's bones from the same CT, closed surfaces, loaded with the
// scene and carried by copy_scene; an open surface is refused with the field and the fix.
TEST(LoadScene, LoadsThePelvisItNamesAndRefusesAnOpenOne) {
  const fs::path dir = test_dir();
  const fs::path file = make_scene(dir);
  EXPECT_TRUE(load_scene(file).pelvis_path.empty());
  EXPECT_EQ(load_scene(file).pelvis.V.rows(), 0);
  write_mesh(file.parent_path() / "pelvis.ply", tetrahedron(-80), MeshFormat::PlyBinary);
  json j = read_json(file);
  j["pelvis"] = "pelvis.ply";
  write_json(file, j);
  const Scene scene = load_scene(file);
  EXPECT_EQ(scene.pelvis_path, file.parent_path() / "pelvis.ply");
  EXPECT_EQ(scene.pelvis.V, tetrahedron(-80).V);
  const Scene copied = load_scene(evar::geometry::copy_scene(scene, dir / "copy"));
  EXPECT_EQ(copied.pelvis.V, tetrahedron(-80).V);
  EXPECT_EQ(copied.pelvis_path.filename(), "pelvis.ply");

  TriangleMesh inward = tetrahedron(-80);
  inward.F.col(1).swap(inward.F.col(2));
  write_mesh(file.parent_path() / "pelvis.ply", inward, MeshFormat::PlyBinary);
  EXPECT_THAT(scene_error(file), HasSubstr("point inward"));

  TriangleMesh open = tetrahedron(-80);
  open.F.conservativeResize(3, 3);  // one face gone: three edges with one face each
  write_mesh(file.parent_path() / "pelvis.ply", open, MeshFormat::PlyBinary);
  const std::string error = scene_error(file);
  EXPECT_THAT(error, HasSubstr("scene.json"));
  EXPECT_THAT(error, HasSubstr("pelvis"));
  EXPECT_THAT(error, HasSubstr("not closed"));
  EXPECT_THAT(error, HasSubstr("closed surface"));
}
