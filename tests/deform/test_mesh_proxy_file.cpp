// A proxy kept in a file beside its mesh: read back exactly, refused (with the file and the
// reason) when damaged or made for another mesh or edge; a scene that names proxy files
// deforms through them exactly as through proxies made at load, and one whose file is stale
// makes its proxy anew and says why.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "evar/deform/mesh_proxy.hpp"
#include "evar/deform/mesh_proxy_file.hpp"
#include "evar/deform/scene_deformation.hpp"
#include "evar/sim/example_scene.hpp"
#include "support/error_message.hpp"
#include "support/temp_dir.hpp"

using namespace evar;
namespace fs = std::filesystem;

namespace {

geometry::Scene fine_scene() {
  sim::ExampleSceneParams p;
  p.iliac_vertices = p.iliac_vertices * 15000 / p.aorta_vertices;
  p.aorta_vertices = 15000;  // edges of about 0.95 mm: every vessel gets a proxy
  return sim::to_scene(sim::make_example_scene(p));
}

std::string bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

void write_bytes(const fs::path& p, const std::string& bytes) { std::ofstream(p, std::ios::binary) << bytes; }

}  // namespace

TEST(MeshProxyFile, AProxyIsReadBackExactly) {
  const test::TempDir dir;
  const geometry::Scene scene = fine_scene();
  const auto& fine = scene.vessels[1].mesh.mesh;
  const deform::MeshProxy made = deform::make_proxy(fine, 1.4);
  const fs::path file = dir.path / "iliac_right.proxy";
  deform::write_mesh_proxy(file, made, fine, 1.4);
  const deform::MeshProxy read = deform::read_mesh_proxy(file, fine, 1.4);
  EXPECT_EQ(read.coarse.V, made.coarse.V);
  EXPECT_EQ(read.coarse.F, made.coarse.F);
  EXPECT_EQ(read.largest_offset_mm, made.largest_offset_mm);
  EXPECT_EQ(read.edge_mm, 1.4);
  ASSERT_EQ(read.bindings.size(), made.bindings.size());
  for (std::size_t i = 0; i < read.bindings.size(); ++i) {
    EXPECT_EQ(read.bindings[i].face, made.bindings[i].face);
    EXPECT_EQ(read.bindings[i].barycentric, made.bindings[i].barycentric);
    EXPECT_EQ(read.bindings[i].offset_in_face, made.bindings[i].offset_in_face);
  }
  // The fingerprint sees any edit, a millionth of a millimetre included.
  geometry::TriangleMesh edited = fine;
  edited.V(7, 2) += 1e-6;
  EXPECT_NE(deform::mesh_fingerprint(edited), deform::mesh_fingerprint(fine));
}

TEST(MeshProxyFile, AStaleOrDamagedFileIsRefusedWithTheFileAndWhy) {
  const test::TempDir dir;
  const geometry::Scene scene = fine_scene();
  const auto& fine = scene.vessels[1].mesh.mesh;
  const fs::path file = dir.path / "iliac_right.proxy";
  deform::write_mesh_proxy(file, deform::make_proxy(fine, 1.4), fine, 1.4);
  const auto refusal = [&](const geometry::TriangleMesh& mesh, double edge_mm, const fs::path& f) {
    return test::error_message<std::runtime_error>([&] { deform::read_mesh_proxy(f, mesh, edge_mm); });
  };
  geometry::TriangleMesh edited = fine;
  edited.V(7, 2) += 0.5;
  EXPECT_NE(refusal(edited, 1.4, file).find(file.string() + ": made for another mesh"), std::string::npos);
  EXPECT_NE(refusal(edited, 1.4, file).find("was the mesh edited after the scene was made?"), std::string::npos);
  EXPECT_NE(refusal(scene.vessels[2].mesh.mesh, 1.4, file).find("made for another mesh"), std::string::npos);
  EXPECT_NE(refusal(fine, 1.2, file).find("made for proxy edges of 1.4 mm, 1.2 mm asked"), std::string::npos);

  const std::string whole = bytes_of(file);
  const fs::path cut = dir.path / "cut.proxy";
  write_bytes(cut, whole.substr(0, whole.size() - 100));
  EXPECT_NE(refusal(fine, 1.4, cut).find("(damaged or cut short)"), std::string::npos) << refusal(fine, 1.4, cut);
  write_bytes(cut, whole.substr(0, 30));
  EXPECT_NE(refusal(fine, 1.4, cut).find("ends inside its"), std::string::npos) << refusal(fine, 1.4, cut);
  write_bytes(cut, "solid iliac\n" + whole);
  EXPECT_NE(refusal(fine, 1.4, cut).find("not an evarnode proxy file"), std::string::npos);
  // Another version's file (the digit in its first 16 bytes) is made anew, saying so.
  std::string older = whole;
  older[14] = '1';
  write_bytes(cut, older);
  EXPECT_NE(refusal(fine, 1.4, cut).find("made by another version of evarnode's proxies (evarnode-proxy1, this one makes "
                                         "evarnode-proxy2)"),
            std::string::npos)
      << refusal(fine, 1.4, cut);
  // A remeshed edge longer than the asked one (bytes 24-31).
  std::string longer = whole;
  const double remeshed = 2.0;
  std::memcpy(longer.data() + 24, &remeshed, sizeof remeshed);
  write_bytes(cut, longer);
  EXPECT_NE(refusal(fine, 1.4, cut).find("remeshed to edges of 2 mm"), std::string::npos) << refusal(fine, 1.4, cut);
  EXPECT_NE(refusal(fine, 1.4, dir.path / "absent.proxy").find("absent.proxy: cannot be opened"), std::string::npos);
  // A number damaged inside: the last binding's first offset (24 bytes from the end).
  std::string damaged = whole;
  const double far = 7.0;
  std::memcpy(damaged.data() + damaged.size() - 24, &far, sizeof far);
  write_bytes(cut, damaged);
  EXPECT_NE(refusal(fine, 1.4, cut).find("damaged: vertex " + std::to_string(fine.V.rows() - 1) + " comes back"),
            std::string::npos)
      << refusal(fine, 1.4, cut);
  // A directory, and a file far bigger than any proxy of this mesh.
  EXPECT_NE(refusal(fine, 1.4, dir.path).find("cannot be opened"), std::string::npos);
  write_bytes(cut, whole + std::string(whole.size() * 8, '\0'));
  EXPECT_NE(refusal(fine, 1.4, cut).find("more than a proxy of this mesh can hold"), std::string::npos) << refusal(fine, 1.4, cut);
  // A binding naming a face the proxy does not have (the last binding's face, 52 bytes from the end).
  std::string bad = whole;
  const std::int32_t face = 1 << 30;
  std::memcpy(bad.data() + bad.size() - 52, &face, sizeof face);
  write_bytes(cut, bad);
  EXPECT_NE(refusal(fine, 1.4, cut).find("names face 1073741824"), std::string::npos) << refusal(fine, 1.4, cut);
}

TEST(MeshProxyFile, ASceneDeformsThroughItsProxyFilesAsThroughProxiesMadeAtLoad) {
  const test::TempDir dir;
  geometry::Scene scene = fine_scene();
  const auto device = sim::make_example_scene({}).device;
  const deform::SceneDeformer made(scene);
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    ASSERT_NE(made.proxy(i), nullptr);
    scene.vessels[i].proxy_path = dir.path / (scene.vessels[i].name + ".proxy");
    deform::write_mesh_proxy(scene.vessels[i].proxy_path, *made.proxy(i), scene.vessels[i].mesh.mesh, 1.4);
  }
  const auto reference = made.deform(device);

  const deform::SceneDeformer read(scene);
  const auto out = read.deform(device);
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    EXPECT_EQ(out.reports[i].proxy_file, scene.vessels[i].proxy_path.string());
    EXPECT_EQ(out.reports[i].proxy_file_unused, "");
    EXPECT_EQ(out.vessels[i].mesh.V, reference.vessels[i].mesh.V) << scene.vessels[i].name;
  }

  // The right iliac's file holds the left's proxy: made anew, said why, same result.
  scene.vessels[1].proxy_path = scene.vessels[2].proxy_path;
  const deform::SceneDeformer stale(scene);
  const auto again = stale.deform(device);
  EXPECT_EQ(again.reports[1].proxy_file, "");
  EXPECT_NE(again.reports[1].proxy_file_unused.find("made for another mesh"), std::string::npos);
  EXPECT_EQ(again.reports[2].proxy_file, scene.vessels[2].proxy_path.string());
  EXPECT_EQ(again.vessels[1].mesh.V, reference.vessels[1].mesh.V);
}

// A proxy made at a finer rung than the asked edge (the example's left iliac at a 14 mm
// edge holds only at 8.96 mm, MeshProxy.AVesselWhoseProxyIsRefused…) is kept for the asked
// edge and read back with the edge it was remeshed to, so deform reports it.
TEST(MeshProxyFile, AProxyMadeAtAFinerRungReadsBackWithItsOwnEdge) {
  const test::TempDir dir;
  const geometry::Scene scene = sim::to_scene(sim::make_example_scene({}));
  ASSERT_EQ(scene.vessels[1].name, "iliac_left");
  const auto& mesh = scene.vessels[1].mesh.mesh;
  const deform::MeshProxy made = deform::make_proxy_or_finer(mesh, 14.0);
  EXPECT_NEAR(made.edge_mm, 8.96, 1e-9);
  const fs::path file = dir.path / "iliac_left.proxy";
  deform::write_mesh_proxy(file, made, mesh, 14.0);
  const deform::MeshProxy read = deform::read_mesh_proxy(file, mesh, 14.0);
  EXPECT_EQ(read.edge_mm, made.edge_mm);
  EXPECT_EQ(read.coarse.V, made.coarse.V);
  // A proxy that does not say its edge, or says one longer than the asked, is not written.
  deform::MeshProxy unsaid = made;
  unsaid.edge_mm = 0.0;
  EXPECT_NE(test::error_message<std::invalid_argument>([&] { deform::write_mesh_proxy(file, unsaid, mesh, 14.0); })
                .find("remeshed to 0"),
            std::string::npos);
}
