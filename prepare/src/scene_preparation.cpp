#include "evar/prepare/scene_preparation.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <array>
#include <cstdio>
#include <map>

#include <Eigen/Geometry>

#include "evar/base/elapsed.hpp"
#include "evar/base/input_error.hpp"
#include "evar/base/quantity_text.hpp"
#include "evar/geometry/centerline_file.hpp"
#include "evar/geometry/ray_caster.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/prepare/centerline_tree.hpp"
#include "evar/prepare/patient_axes.hpp"
#include "evar/prepare/surface_centerlines.hpp"
#include "evar/prepare/surface_split.hpp"

namespace evar::prepare {
namespace {

// The aorta must run from the bifurcation to its inlet within this angle of the head.
const double kCosHeadward = std::cos(45.0 * M_PI / 180.0);
// An ostium clicked farther than this from the wall is in another frame, not on it.
constexpr double kMaxOstiumOffWallMm = 10.0;

std::string lower_extension(const std::filesystem::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return e;
}

// The centerline curves of a VMTK .vtp or of a markups file's curves (in the file's frame
// for .vtp; markups are patient coordinates by their format).
std::vector<geometry::CenterlineCurve> read_centerline_curves(const std::filesystem::path& path, bool& in_patient_frame) {
  std::vector<geometry::CenterlineCurve> curves;
  if (lower_extension(path) == ".vtp") {
    const auto file = geometry::read_centerline_file(path);
    in_patient_frame = file.space != geometry::MeshSpace::Undeclared;
    return file.curves;
  }
  in_patient_frame = true;
  for (const auto& m : geometry::read_markups(path)) {
    if (m.type != "Curve" && m.type != "ClosedCurve") continue;
    geometry::CenterlineCurve c;
    for (const auto& p : m.points) c.points.push_back(p.position_lps);
    curves.push_back(std::move(c));
  }
  if (curves.empty())
    throw base::InputError(path.string() + ": holds no Curve markup; centerlines are curves (3D Slicer: Extract "
                                           "Centerline writes them) or a VMTK .vtp");
  return curves;
}

// The points of `line` from arc length `from_mm` on, with their radii.
void tail_from(const geometry::Polyline& line, const std::vector<double>& radius, double from_mm, geometry::Polyline& out,
               std::vector<double>& out_radius) {
  const auto arc = geometry::arc_lengths(line);
  out.push_back(geometry::point_at(line, arc, from_mm));
  const auto k = static_cast<std::size_t>(std::upper_bound(arc.begin(), arc.end(), from_mm) - arc.begin());
  out_radius.push_back(radius[std::min(k, radius.size() - 1)]);
  for (std::size_t i = k; i < line.size(); ++i)
    if (arc[i] > from_mm + 1e-6) out.push_back(line[i]), out_radius.push_back(radius[i]);
}

}  // namespace

int weld_coincident_vertices(geometry::TriangleMesh& mesh) {
  std::map<std::array<double, 3>, int> first;
  std::vector<int> to(static_cast<std::size_t>(mesh.V.rows()));
  std::vector<Eigen::Index> kept;
  for (Eigen::Index i = 0; i < mesh.V.rows(); ++i) {
    const std::array<double, 3> key{mesh.V(i, 0) + 0.0, mesh.V(i, 1) + 0.0, mesh.V(i, 2) + 0.0};  // -0 == +0
    const auto [it, fresh] = first.try_emplace(key, static_cast<int>(kept.size()));
    if (fresh) kept.push_back(i);
    to[static_cast<std::size_t>(i)] = it->second;
  }
  const int joined = static_cast<int>(mesh.V.rows() - static_cast<Eigen::Index>(kept.size()));
  if (joined == 0) return 0;
  geometry::Vertices V(static_cast<Eigen::Index>(kept.size()), 3);
  for (std::size_t k = 0; k < kept.size(); ++k) V.row(static_cast<Eigen::Index>(k)) = mesh.V.row(kept[k]);
  geometry::Faces F(mesh.F.rows(), 3);
  Eigen::Index n = 0;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    const int a = to[static_cast<std::size_t>(mesh.F(f, 0))], b = to[static_cast<std::size_t>(mesh.F(f, 1))],
              c = to[static_cast<std::size_t>(mesh.F(f, 2))];
    if (a != b && b != c && a != c) F.row(n++) << a, b, c;
  }
  F.conservativeResize(n, 3);
  mesh.V = std::move(V);
  mesh.F = std::move(F);
  return joined;
}

PreparedScene prepare_scene(const SceneInputs& in) {
  const auto t0 = std::chrono::steady_clock::now();
  PreparedScene out;
  geometry::LoadedMesh surface = geometry::read_mesh(in.surface);
  // Pieces stored apart (VMTK's branch split keeps each branch's vertices of its own)
  // are one surface again once vertices at the same position are one.
  if (const int joined = weld_coincident_vertices(surface.mesh); joined > 0)
    out.notes.push_back(std::to_string(joined) + " vertices lay exactly on others (pieces stored apart, as VMTK's "
                        "branch split stores them): joined");
  geometry::validate_mesh(surface.mesh, in.surface.string());
  // Faces wound outward, as evarnode's meshes are: a closed surface whose signed volume is
  // negative (VMTK writes its surfaces so) is turned.
  if (geometry::is_closed(surface.mesh)) {
    double volume6 = 0.0;
    const auto& V = surface.mesh.V;
    for (Eigen::Index f = 0; f < surface.mesh.F.rows(); ++f)
      volume6 += V.row(surface.mesh.F(f, 0)).dot(
          V.row(surface.mesh.F(f, 1)).transpose().cross(V.row(surface.mesh.F(f, 2)).transpose()));
    if (volume6 < 0.0) {
      surface.mesh.F.col(1).swap(surface.mesh.F.col(2));
      out.notes.push_back("the surface's faces were wound inward (normals into the lumen): turned outward");
    }
  }
  out.surface_format = surface.format;
  bool centerlines_in_patient_frame = true;
  std::vector<geometry::CenterlineCurve> curves;
  if (!in.centerlines.empty()) curves = read_centerline_curves(in.centerlines, centerlines_in_patient_frame);

  // The frame: the file's tag, else --axes, else LPS as Slicer reads an untagged file.
  out.axes = "LPS";
  Eigen::Matrix3d to_lps = Eigen::Matrix3d::Identity();  // file axes -> LPS (--axes)
  if (!in.axes.empty()) {
    if (surface.space != geometry::MeshSpace::Undeclared)
      throw base::InputError(in.surface.string() + ": declares SPACE=" +
                             (surface.space == geometry::MeshSpace::Ras ? "RAS" : "LPS") +
                             " in its header, so --axes " + in.axes + " cannot also say which way its axes point; "
                             "leave out --axes");
    const PatientAxes axes = parse_patient_axes(in.axes);
    out.axes = axes.code;
    to_lps = axes.to_lps;
    for (Eigen::Index i = 0; i < surface.mesh.V.rows(); ++i)
      surface.mesh.V.row(i) = (axes.to_lps * surface.mesh.V.row(i).transpose()).transpose();
    if (!centerlines_in_patient_frame)
      for (auto& c : curves)
        for (auto& p : c.points) p = axes.to_lps * p;
    out.notes.push_back("the surface's axes point to " + axes.code + " (from --axes); turned into LPS");
  } else if (surface.space == geometry::MeshSpace::Ras) {
    out.axes = "RAS";
  }

  // One BVH of the surface, in LPS, for every nearest-wall question below.
  const geometry::RayCaster walls(surface.mesh, geometry::RayCaster::BuildQuality::Low);
  // The centerlines given, else the surface's own.
  const std::string centerline_source =
      in.centerlines.empty() ? in.surface.string() + " (its centerlines, computed)" : in.centerlines.string();
  std::vector<geometry::CenterlineCurve> paths;
  if (in.centerlines.empty()) {
    SurfaceCenterlines computed = centerlines_from_surface(surface.mesh, walls, in.surface.string());
    paths = std::move(computed.paths);
    std::string extra;
    if (computed.openings_closed > 0)
      extra += "; " + std::to_string(computed.openings_closed) + " openings closed for it";
    if (computed.spurs_dropped > 0)
      extra += "; " + std::to_string(computed.spurs_dropped) + " ends that never left their parent's lumen dropped";
    out.notes.push_back("no centerlines given: computed from the surface's mean-curvature-flow skeleton (CGAL; " +
                        std::to_string(computed.skeleton_points) + " points, " + std::to_string(paths.size() + 1) +
                        " ends, " + base::quantity_text(computed.skeleton_ms, "ms", 0) + extra +
                        "); check them on the picture");
  } else {
    paths = centerline_paths(curves, in.centerlines.string());
  }
  // Radii where the centerlines came without: the distance to the nearest wall.
  bool estimated = false;
  for (auto& p : paths)
    if (p.radius_mm.size() != p.points.size()) p.radius_mm = radius_from_surface(walls, p.points), estimated = true;
  if (estimated) out.notes.push_back("the centerlines carry no radius: taken from the surface (distance to the nearest wall)");
  const BifurcationTree tree = bifurcation_tree(paths, centerline_source);
  if (!tree.note.empty())
    out.notes.push_back((in.centerlines.empty() ? std::string("the computed centerlines")
                                                : in.centerlines.filename().string()) + ": " + tree.note);
  out.inlet = tree.trunk.front();
  out.bifurcation = tree.trunk.back();

  // Head to foot, from the anatomy: the inlet lies toward the head (+z in LPS).
  const Eigen::Vector3d headward = (tree.trunk.front() - tree.trunk.back()).normalized();
  if (!(headward.z() >= kCosHeadward)) {
    const std::string along = file_axis_name(to_lps.transpose() * headward);
    std::string example;
    const char axis = along[1];
    const bool plus = along[0] == '+';
    if (axis == 'y') example = plus ? "RSP" : "RIA";
    else if (axis == 'x') example = plus ? "SPR" : "IPL";
    else example = plus ? "LPS" : "RAI";
    throw base::InputError(
        in.surface.string() + ": its aorta runs from the bifurcation to its inlet along the file's " + along +
        (in.axes.empty() && surface.space == geometry::MeshSpace::Undeclared
             ? " axis, but the file declares no coordinate system, so it is read as LPS, where the head is +z"
             : " axis, which is not toward the head in " + out.axes) +
        ": the surface is in another frame (a segmentation in the image's own axes, or a mirrored export). Say which "
        "patient direction each file axis points to with --axes (an aorta running to " + along + " fits for example --axes " +
        example + "; only you can tell left from right), or export the surface in patient coordinates (3D Slicer: "
        "Segmentations > Export to files). Nothing is rotated without being asked");
  }

  const SurfacePieces pieces = split_surface(surface.mesh, walls, tree, centerline_source);

  // The patient's right is -x in LPS.
  const int right = tree.branches[0].back().x() < tree.branches[1].back().x() ? 0 : 1;

  // The aortic centerline runs on from where the paths part, between them, as long as that
  // stays well inside the lumen (down toward the crotch), so the aorta's control points
  // reach the bottom of its piece.
  PreparedVessel aorta{"aorta", "aorta", pieces.aorta, tree.trunk, tree.trunk_radius_mm};
  {
    const auto arc0 = geometry::arc_lengths(tree.branches[0]);
    const auto arc1 = geometry::arc_lengths(tree.branches[1]);
    const double end_r = tree.trunk_radius_mm.back();
    const double limit = std::min(pieces.cut_arc_mm[0], pieces.cut_arc_mm[1]);
    double extended = 0.0;
    for (double s = 0.5; s <= limit; s += 0.5) {
      const Eigen::Vector3d m =
          0.5 * (geometry::point_at(tree.branches[0], arc0, s) + geometry::point_at(tree.branches[1], arc1, s));
      const auto q = walls.closest_point(m);
      if (!q || q->distance_mm < end_r / 3.0) break;
      aorta.centerline.push_back(m);
      aorta.radius_mm.push_back(q->distance_mm);
      extended = s;
    }
    if (extended > 0.0)
      out.notes.push_back("the aortic centerline runs on " + base::quantity_text(extended, "mm", 1) +
                          " past where the iliac paths part, between them, toward the crotch");
  }
  out.vessels.push_back(std::move(aorta));
  for (const int b : {right, 1 - right}) {
    PreparedVessel iliac{b == right ? "iliac_right" : "iliac_left", "iliac", pieces.iliacs[static_cast<std::size_t>(b)], {}, {}};
    tail_from(tree.branches[static_cast<std::size_t>(b)], tree.branch_radius_mm[static_cast<std::size_t>(b)],
              pieces.cut_arc_mm[static_cast<std::size_t>(b)], iliac.centerline, iliac.radius_mm);
    out.vessels.push_back(std::move(iliac));
  }
  for (const auto& v : out.vessels) geometry::validate_mesh(v.mesh, in.surface.string() + " (its " + v.name + " piece)");

  // Ostia clicked in Slicer: onto the wall.
  if (!in.ostia.empty()) {
    for (const auto& p : geometry::read_fiducials(in.ostia)) {
      const auto q = walls.closest_point(p.position_lps);
      if (!q || q->distance_mm > kMaxOstiumOffWallMm)
        throw base::InputError(in.ostia.string() + ": ostium '" + p.label + "' lies " +
                               base::quantity_text(q ? q->distance_mm : INFINITY, "mm", 1) + " from the surface (at most " + base::quantity_text(kMaxOstiumOffWallMm, "mm", 1) +
                               "): is it in the surface's coordinates? Place it on the vessel wall in 3D Slicer");
      out.landmarks.push_back({p.label, q->point});
    }
    out.notes.push_back(std::to_string(out.landmarks.size()) + " ostia from " + in.ostia.filename().string() +
                        ", each moved onto the nearest wall");
  } else if (!tree.side_branches.empty()) {
    // Side-branch stubs the centerlines reach into: their ostia, named by where they
    // branch and point (rename them in 3D Slicer where the guess is wrong).
    std::map<std::string, int> used;
    std::string names;
    for (const auto& side : tree.side_branches) {
      const Eigen::Vector3d d = side.outlet - side.leaves_parent;
      std::string label;
      if (side.parent >= 0) {
        label = side.parent == right ? "internal_iliac_right" : "internal_iliac_left";
      } else if (std::abs(d.x()) >= std::abs(d.y())) {
        label = d.x() > 0.0 ? "renal_left" : "renal_right";  // +x is the patient's left in LPS
      } else {
        label = d.y() < 0.0 ? "mesenteric" : "posterior_branch";  // -y is anterior
      }
      if (const int n = ++used[label]; n > 1) label += "_" + std::to_string(n);
      const auto q = walls.closest_point(side.leaves_parent);
      if (!q) continue;
      out.landmarks.push_back({label, q->point});
      names += (names.empty() ? "" : ", ") + label;
    }
    out.notes.push_back(std::to_string(out.landmarks.size()) + " side-branch stubs found along the centerlines, their " +
                        "ostia offered as landmarks (" + names + "; named by where they branch and point: rename "
                        "them in 3D Slicer where that is wrong, or give your own with --ostia)");
  } else {
    out.notes.push_back("no ostia given (--ostia) and the centerlines reach into no side-branch stub: the scene has no "
                        "landmarks; click them on the wall in 3D Slicer and give them with --ostia");
  }
  out.prepare_ms = base::ms_since(t0);
  return out;
}

std::filesystem::path write_prepared_scene(const PreparedScene& scene, const std::filesystem::path& dir,
                                           double device_thickness_mm) {
  std::filesystem::create_directories(dir);
  const std::string ext = geometry::extension_for(scene.surface_format);
  geometry::SceneManifest manifest;
  manifest.device_thickness_mm = device_thickness_mm;
  for (const auto& v : scene.vessels) {
    const std::string mesh = v.name + ext, centerline = v.name + ".centerline.mrk.json";
    geometry::write_mesh(dir / mesh, v.mesh, scene.surface_format, geometry::MeshSpace::Lps);
    geometry::Markup curve{"Curve", v.name + " centerline", {}};
    for (std::size_t i = 0; i < v.centerline.size(); ++i)
      curve.points.push_back({v.name + "-" + std::to_string(i + 1), v.centerline[i]});
    geometry::write_markups(dir / centerline, {curve});
    manifest.vessels.emplace_back(v.name, v.kind, mesh, centerline);
  }
  if (!scene.landmarks.empty()) {
    geometry::write_markups(dir / "landmarks.mrk.json", {geometry::Markup{"Fiducial", "ostia", scene.landmarks}});
    manifest.landmarks = "landmarks.mrk.json";
  }
  const auto json = dir / "scene.json";
  geometry::write_scene_manifest(json, manifest);
  return json;
}

}  // namespace evar::prepare
