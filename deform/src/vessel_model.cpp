#include <Eigen/Geometry>
#include <algorithm>
#include <limits>
#include <chrono>
#include <cmath>
#include <optional>

#include "evar/base/elapsed.hpp"
#include "evar/base/input_error.hpp"
#include "evar/deform/registration_tether.hpp"
#include "vessel_model.hpp"

namespace evar::deform::detail {

namespace {
using Clock = std::chrono::steady_clock;
using base::ms_since;

// Where each vertex and skeleton point lies along the vessel (the arc length of its foot on
// the centerline) and where it is at rest: the solver's coarse space (coarse_space.hpp).
ArapKnots vessel_knots(const geometry::Vessel& v, const Skeleton& skeleton, int vertices, int centres, double spacing_mm) {
  ArapKnots knots;
  if (!(spacing_mm > 0.0) || v.centerline.size() < 2) return knots;
  knots.spacing_mm = spacing_mm;
  const auto& V = v.mesh.mesh.V;
  knots.rest.resize(vertices + centres, 3);
  knots.arc_of_unknown.resize(static_cast<std::size_t>(vertices + centres));
  const geometry::PolylineProjector onto_centerline(v.centerline);
  int segment = -1;
  for (int k = 0; k < vertices; ++k) {
    knots.rest.row(k) = V.row(k);
    knots.arc_of_unknown[static_cast<std::size_t>(k)] =
        onto_centerline.project(V.row(k).transpose(), segment, &segment).arc_length_mm;
  }
  for (int k = 0; k < centres; ++k) {
    knots.rest.row(vertices + k) = skeleton.centres[static_cast<std::size_t>(k)].transpose();
    knots.arc_of_unknown[static_cast<std::size_t>(vertices + k)] = skeleton.arc_mm[static_cast<std::size_t>(k)];
  }
  return knots;
}

}  // namespace

std::unique_ptr<VesselModel> make_model(const geometry::Vessel& v, const DeformOptions& options) {
  auto m = std::make_unique<VesselModel>();
  m->vessel = &v;
  const auto& mesh = v.mesh.mesh;
  auto t0 = Clock::now();
  m->caster.emplace(mesh);
  m->closed = geometry::is_closed(mesh);
  m->skeleton = build_skeleton(*m->caster, v.centerline, options.skeleton);
  m->skeleton_ms = ms_since(t0);
  if (m->skeleton.centres.empty()) {
    // Usually the two are in different units or frames (metres or cm; RAS for LPS): say
    // where each lies, so the cause shows.
    const auto box = [](const auto& points) {
      Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
      for (const auto& p : points) lo = lo.cwiseMin(Eigen::Vector3d(p)), hi = hi.cwiseMax(Eigen::Vector3d(p));
      char text[160];
      std::snprintf(text, sizeof text, "(%.1f, %.1f, %.1f) to (%.1f, %.1f, %.1f)", lo.x(), lo.y(), lo.z(), hi.x(),
                    hi.y(), hi.z());
      return std::string(text);
    };
    std::vector<Eigen::Vector3d> corners;
    for (Eigen::Index k = 0; k < mesh.V.rows(); ++k) corners.emplace_back(mesh.V.row(k).transpose());
    throw base::InputError(v.centerline_path.string() + ": the centerline of vessel '" + v.name +
                               "' does not run inside its mesh " + v.mesh_path.string() +
                               " (no slicing plane hit the wall). The mesh spans " + box(corners) +
                               " mm, the centerline " + box(v.centerline) +
                               " mm: both must be millimetres in patient LPS (a mesh in metres or cm, or saved in "
                               "RAS without SPACE=RAS in its header, lies elsewhere; for the latter, declare "
                               "\"mesh_coordinate_system\": \"RAS\" for the vessel in the scene)");
  }
  m->radius = radius_profile(m->skeleton);

  t0 = Clock::now();
  const int n = static_cast<int>(mesh.V.rows());
  const int centres = options.use_skeleton ? static_cast<int>(m->skeleton.centres.size()) : 0;
  ArapTerms terms = surface_arap_terms(mesh.V, cotangent_weights(mesh), n + centres);
  if (centres > 0) append_skeleton_terms(terms, mesh, m->skeleton, n, options.skeleton.weight);
  m->system = std::make_shared<const ArapSystem>(std::move(terms), options.arap,
                                                 registration_tether(mesh, n + centres, options.tether_length_mm),
                                                 v.kind == geometry::VesselKind::Iliac
                                                     ? vessel_knots(v, m->skeleton, n, centres, options.coarse_knot_spacing_mm)
                                                     : ArapKnots{});
  // A vertex no face uses has no shape to keep: it stays where it is (otherwise it would
  // be a part with nothing to determine it).
  std::vector<char> used(static_cast<std::size_t>(n), 0);
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int j = 0; j < 3; ++j) used[static_cast<std::size_t>(mesh.F(f, j))] = 1;
  for (int k = 0; k < n; ++k)
    if (!used[static_cast<std::size_t>(k)]) m->isolated.push_back(k);
  m->weights_ms = ms_since(t0);
  return m;
}

// The iliac's top vertices and where each sits on the aortic surface. They are bound to
// the deformed aorta at that closest point (barycentric in its face), so neighbouring
// top vertices move alike and the junction follows the aorta without tearing the ring
// (a nearest-vertex binding jumps between aortic vertices that moved differently).
// How far apart they may be (the report's junction_gap_mm) only the constructor's start
// check bounds, and only for a closed aorta: a start outside it is at most the radius r +
// 5 mm from its wall, and a bound vertex is within bind_length + 3r of the start (the
// selection's reach; the top ring itself about r + bind_length), so the gap stays under
// 4r + 5 mm + bind_length (about 2r + 5 mm + bind_length on the ring). A start inside the
// aorta, or an open aortic mesh (no inside to test), binds to the nearest wall however far.
void bind_junction(VesselModel& m, const geometry::TriangleMesh& aorta, double bind_length_mm) {
  const auto& v = *m.vessel;
  const auto& V = v.mesh.mesh.V;
  // Only vertices near the proximal end can be within bind_length of it along the
  // centerline (a vertex is at most a few radii from its foot): skip the rest cheaply.
  const double reach = bind_length_mm + 3.0 * m.radius.at(0.0);
  const geometry::PolylineProjector onto_centerline(v.centerline);
  int segment = -1;
  std::vector<int> top;
  std::vector<Eigen::Vector3d> points;
  for (Eigen::Index k = 0; k < V.rows(); ++k) {
    const Eigen::Vector3d p = V.row(k).transpose();
    if ((p - v.centerline.front()).squaredNorm() > reach * reach) continue;
    const auto foot = onto_centerline.project(p, segment, &segment);
    if (foot.arc_length_mm > bind_length_mm) continue;
    top.push_back(static_cast<int>(k));
    points.push_back(p);
    m.top_centroid += p;
  }
  const auto on_aorta = geometry::closest_points_on_mesh(aorta, points);
  for (std::size_t i = 0; i < top.size(); ++i) {
    m.junction.emplace_back(top[i], on_aorta[i]);
    m.junction_gap_mm = std::max(m.junction_gap_mm, on_aorta[i].distance_mm);
  }
  if (!m.junction.empty()) {
    m.top_centroid /= static_cast<double>(m.junction.size());
    return;
  }
  // None: say where the mesh does begin, for the message that refuses it.
  m.mesh_begins_at_mm = std::numeric_limits<double>::infinity();
  m.nearest_vertex_to_start_mm = std::numeric_limits<double>::infinity();
  segment = -1;
  for (Eigen::Index k = 0; k < V.rows(); ++k) {
    const Eigen::Vector3d p = V.row(k).transpose();
    m.nearest_vertex_to_start_mm = std::min(m.nearest_vertex_to_start_mm, (p - v.centerline.front()).norm());
    m.mesh_begins_at_mm = std::min(m.mesh_begins_at_mm, onto_centerline.project(p, segment, &segment).arc_length_mm);
  }
}

}  // namespace evar::deform::detail
