#pragma once
// The patient scene (scene.json, format "evarnode-scene" version 1): vessel meshes with
// their centerlines, the landmarks and the device thickness. Paths inside the file are
// relative to it.
#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "evar/geometry/markups.hpp"
#include "evar/geometry/mesh_io.hpp"

namespace evar::geometry {

enum class VesselKind { Aorta, Iliac };

struct Vessel {
  std::string name;
  VesselKind kind = VesselKind::Aorta;
  std::filesystem::path mesh_path;        ///< resolved (absolute or relative to cwd)
  std::filesystem::path centerline_path;  ///< resolved
  /// scene.json's optional "proxy": deform's proxy for this mesh kept beside it
  /// (evarnode scene writes it; deform/mesh_proxy_file.hpp), resolved; empty when none.
  /// A cache: deform makes the proxy anew, and says so, when it is missing or stale.
  std::filesystem::path proxy_path;
  LoadedMesh mesh;                        ///< validated, in LPS
  /// scene.json's "mesh_coordinate_system" for a mesh file that declares none (3D Slicer
  /// before 4.11 saved RAS without saying so); Undeclared when the field is absent.
  MeshSpace declared_mesh_space = MeshSpace::Undeclared;
  std::vector<Eigen::Vector3d> centerline;  ///< LPS mm, proximal to distal
};

struct Scene {
  std::filesystem::path file;
  std::vector<Vessel> vessels;
  std::filesystem::path landmarks_path;   ///< empty when the scene has no landmarks
  std::vector<ControlPoint> landmarks;    ///< LPS mm, labels kept
  double device_thickness_mm = 0.0;
  /// scene.json's optional "pelvis": the pelvis's bones from the same CT (sacrum, hip bones,
  /// femoral heads; closed surfaces, one file, any mesh format), so the pelvis can be found
  /// in the fluoroscopy (geometry/pelvis_registration.hpp). Empty path and mesh when none.
  std::filesystem::path pelvis_path;
  TriangleMesh pelvis;                    ///< LPS mm
};

/// Loads scene.json and everything it names. Throws InputError naming the file and field.
/// Checks: format/version, coordinate_system "LPS", units "mm", at least one vessel,
/// exactly one of kind "aorta", unique names, device_thickness_mm finite and >= 0,
/// centerlines with at least 2 points, a vessel's optional "mesh_coordinate_system" ("LPS"
/// or "RAS") agreeing with what its mesh file declares, if it declares anything, and an
/// optional "pelvis" mesh made of closed surfaces.
Scene load_scene(const std::filesystem::path& scene_json);

/// Plain description used to write a scene.json (paths relative to the scene file).
struct SceneManifest {
  struct Entry {
    Entry(std::string name_, std::string kind_, std::string mesh_, std::string centerline_,
          std::string mesh_coordinate_system_ = {})
        : name(std::move(name_)),
          kind(std::move(kind_)),
          mesh(std::move(mesh_)),
          centerline(std::move(centerline_)),
          mesh_coordinate_system(std::move(mesh_coordinate_system_)) {}
    std::string name, kind, mesh, centerline;
    std::string mesh_coordinate_system;  ///< "LPS", "RAS", or empty: not written
    std::string proxy;                   ///< the proxy file, or empty: not written
  };
  std::vector<Entry> vessels;
  std::string landmarks;  ///< may be empty
  std::string pelvis;     ///< the pelvis's bones; may be empty
  double device_thickness_mm = 0.9;
};
void write_scene_manifest(const std::filesystem::path& scene_json, const SceneManifest& manifest);

/// Copies a loaded scene's files (meshes, centerlines, landmarks, as they are) into
/// `directory` under names made from the vessel names, with a scene.json naming them, so a
/// recorded session carries its own patient. Returns the new scene.json.
std::filesystem::path copy_scene(const Scene& scene, const std::filesystem::path& directory);

const char* to_string(VesselKind kind);

}  // namespace evar::geometry
