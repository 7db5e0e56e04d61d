#pragma once
// From one aorto-iliac surface as a segmentation tool exports it, with its centerlines, to
// the scene evarnode deforms: the surface cut into the aorta and the two iliacs, their
// centerlines trimmed and run proximal to distal, the iliacs told right from left, the
// clicked ostia snapped to the wall, all in patient LPS (never rotated silently: a file
// whose head-to-foot axis is not LPS's is refused unless its axes are given).
#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "evar/geometry/markups.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/polyline.hpp"

namespace evar::prepare {

struct SceneInputs {
  std::filesystem::path surface;      ///< STL, PLY, OBJ, VTK or VTP
  /// VMTK .vtp (paths or branches) or 3D Slicer markups curves (.mrk.json); empty: computed
  /// from the surface (surface_centerlines.hpp)
  std::filesystem::path centerlines;
  std::filesystem::path ostia;        ///< optional: 3D Slicer fiducials (.mrk.json), clicked on the wall
  std::string axes;                   ///< optional: the surface file's axes (patient_axes.hpp); "" = its tag, else LPS
};

struct PreparedVessel {
  std::string name, kind;  ///< "aorta" / "aorta", "iliac_right" / "iliac", "iliac_left" / "iliac"
  geometry::TriangleMesh mesh;
  geometry::Polyline centerline;  ///< proximal to distal
  std::vector<double> radius_mm;  ///< per centerline point
};

struct PreparedScene {
  std::vector<PreparedVessel> vessels;  ///< aorta, iliac_right, iliac_left
  std::vector<geometry::ControlPoint> landmarks;
  geometry::MeshFormat surface_format = geometry::MeshFormat::StlBinary;
  std::string axes;                     ///< the code the surface was read with ("LPS" when it said nothing)
  Eigen::Vector3d bifurcation = Eigen::Vector3d::Zero();  ///< where the iliac paths part (LPS mm)
  Eigen::Vector3d inlet = Eigen::Vector3d::Zero();        ///< the aortic inlet (LPS mm)
  std::vector<std::string> notes;  ///< what was decided, for the log and the report
  double prepare_ms = 0.0;
};

/// Joins vertices at bit-identical positions (faces renumbered, those left without area
/// dropped). Returns how many were joined.
int weld_coincident_vertices(geometry::TriangleMesh& mesh);

/// Reads and prepares. base::InputError naming the file (or option) and saying how to fix
/// it for: a surface whose centerlines cannot be computed (when none are given), centerlines that make no aorto-iliac tree, a surface whose
/// aorta does not run toward the head in LPS (with the axis it runs along and the --axes
/// code that would say so), a cut that does not separate an iliac, an ostium far from
/// the wall.
PreparedScene prepare_scene(const SceneInputs& inputs);

/// Writes DIR/aorta.<ext>, iliac_right.<ext>, iliac_left.<ext> (the surface's format, LPS
/// declared), their centerline markups, landmarks.mrk.json (when there are any) and
/// scene.json. Returns the scene.json path.
std::filesystem::path write_prepared_scene(const PreparedScene& scene, const std::filesystem::path& dir,
                                           double device_thickness_mm);

}  // namespace evar::prepare
