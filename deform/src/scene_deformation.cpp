#include "evar/deform/scene_deformation.hpp"

#include <Eigen/Geometry>
#include <chrono>
#include <exception>
#include <future>
#include <numeric>
#include <set>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>

#include "evar/deform/landmark_binding.hpp"
#include "evar/deform/registration_tether.hpp"
#include "evar/base/elapsed.hpp"
#include "evar/geometry/closest_point.hpp"
#include "evar/base/input_error.hpp"

namespace evar::deform {
namespace {

using Clock = std::chrono::steady_clock;
using base::ms_since;

}  // namespace

// What is computed once per vessel, before any device is known.
struct SceneDeformer::VesselModel {
  const geometry::Vessel* vessel = nullptr;
  std::optional<geometry::RayCaster> caster;
  Skeleton skeleton;
  RadiusProfile radius;
  std::shared_ptr<const ArapSystem> system;  ///< surface (+ skeleton) terms, tether, ordering
  std::vector<int> isolated;                 ///< vertices no face uses
  bool closed = false;                       ///< the mesh has an inside (ray parity works)
  /// Iliacs: the top vertices (foot on the centerline within bind_length of its start),
  /// each with the closest point of the undeformed aortic surface (face, barycentric).
  std::vector<std::pair<int, geometry::SurfacePoint>> junction;
  Eigen::Vector3d top_centroid = Eigen::Vector3d::Zero();  ///< of the junction vertices
  double junction_gap_mm = 0.0;  ///< the farthest junction vertex from its aortic point
  double skeleton_ms = 0.0, weights_ms = 0.0;
};

namespace {

using VesselModel = SceneDeformer::VesselModel;

// Ostium landmarks are placed on the wall; 10 mm off is already a different structure.
constexpr double kMaxLandmarkDistanceMm = 10.0;


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
  if (!m.junction.empty()) m.top_centroid /= static_cast<double>(m.junction.size());
}

// The deformed centerline: the mean of each skeleton plane's wall hits, evaluated on the
// deformed surface (the centres themselves are unknowns only when the skeleton is on).
geometry::Polyline deformed_centerline(const VesselModel& m, const geometry::Vertices& V) {
  const auto& F = m.vessel->mesh.mesh.F;
  std::vector<Eigen::Vector3d> sum(m.skeleton.centres.size(), Eigen::Vector3d::Zero());
  std::vector<int> count(m.skeleton.centres.size(), 0);
  for (const auto& s : m.skeleton.spokes) {
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (int j = 0; j < 3; ++j) p += s.barycentric[j] * V.row(F(s.face, j)).transpose();
    sum[static_cast<std::size_t>(s.centre)] += p;
    ++count[static_cast<std::size_t>(s.centre)];
  }
  geometry::Polyline out;
  for (std::size_t k = 0; k < sum.size(); ++k) out.push_back(sum[k] / count[k]);
  return out;
}

// Skeleton-based (or plain) ARAP for one vessel: device handles plus `fixed` vertex
// targets (the iliac's junction; they win over handles). Without anchors the whole
// vessel may move and sweep its wall across device points that were inside before, so
// handles are re-selected on the deformed surface and the solve repeated (warm-started)
// until no new handle appears or `containment_rounds` is reached.
geometry::Vertices deform_vessel(const VesselModel& m, const geometry::Polyline& device,
                                 const std::map<int, Eigen::Vector3d>& fixed, const DeformOptions& options,
                                 const LumenTest& in_other_lumen, const geometry::Vertices* previous,
                                 VesselReport& report) {
  const auto& mesh = m.vessel->mesh.mesh;
  const int n = static_cast<int>(mesh.V.rows());
  auto t0 = Clock::now();
  ControlPointOptions control = options.control;
  // The device runs through an iliac from its distal end to the aorta: its sections are
  // paired with the device in order (ordered_pairing.hpp). In the aorta it ends anywhere.
  control.pair_in_order = options.control.pair_in_order && m.vessel->kind == geometry::VesselKind::Iliac;
  // It enters at the junction, which moves with the aorta's surface where the iliac's top
  // is bound to it: the bound vertices' mean shift carries the centerline's first point.
  std::optional<Eigen::Vector3d> entry;
  if (control.pair_in_order && !fixed.empty()) {
    Eigen::Vector3d shift = Eigen::Vector3d::Zero();
    for (const auto& [v, p] : fixed) shift += p - mesh.V.row(v).transpose();
    entry = m.vessel->centerline.front() + shift / static_cast<double>(fixed.size());
  }
  auto handles = device.empty() ? std::vector<Handle>{}
                                : select_control_points(mesh, *m.caster, m.vessel->centerline, m.radius, device,
                                                        control, in_other_lumen, entry);
  report.control_points = static_cast<int>(handles.size());
  report.timings.control_points_ms += ms_since(t0);
  if (handles.empty() && fixed.empty()) return mesh.V;

  const int centres = m.system->num_unknowns() - n;
  report.skeleton_points = centres > 0 ? centres + static_cast<int>(m.skeleton.spokes.size()) : 0;

  std::map<int, Eigen::Vector3d> targets = handle_vertex_targets(mesh, handles);
  for (const auto& [v, p] : fixed) targets[v] = p;
  for (const int v : m.isolated) targets.emplace(v, mesh.V.row(v).transpose());
  Positions X;
  for (int round = 0;; ++round) {
    std::vector<int> constrained;
    Positions rows(static_cast<Eigen::Index>(targets.size()), 3);
    for (const auto& [v, p] : targets) {
      rows.row(static_cast<Eigen::Index>(constrained.size())) = p.transpose();
      constrained.push_back(v);
    }
    const ArapSolver solver(m.system, constrained);
    report.timings.factor_ms += solver.factor_ms();
    if (round == 0 && previous) {
      // Warm start from the previous frame: its surface, and skeleton centres at the
      // middle of their wall hits there (solve() puts the new targets in).
      X.resize(m.system->num_unknowns(), 3);
      X.topRows(n) = *previous;
      if (centres > 0) {
        const auto cl = deformed_centerline(m, *previous);
        for (int k = 0; k < centres; ++k) X.row(n + k) = cl[static_cast<std::size_t>(k)].transpose();
      }
    }
    if (round > 0)  // warm start: the previous round's shape with the new targets
      for (std::size_t c = 0; c < constrained.size(); ++c) X.row(constrained[c]) = rows.row(static_cast<Eigen::Index>(c));
    const ArapResult r = (round > 0 || previous) ? solver.solve(rows, &X) : solver.solve(rows);
    report.timings.iterate_ms += r.init_ms + r.iterate_ms;
    report.iterations += r.iterations;
    report.anderson_rejections += r.anderson_rejections;
    report.coarse_fallbacks += r.coarse_fallbacks;
    report.converged = r.converged;
    report.final_energy = r.energy.empty() ? 0.0 : r.energy.back();
    report.constrained_vertices = static_cast<int>(constrained.size());
    report.rounds = round + 1;
    if (!r.X.allFinite())
      throw std::runtime_error("vessel '" + m.vessel->name + "': the ARAP solve produced non-finite positions");
    X = r.X;
    // Rounds need a deformed centerline: two skeleton planes at least.
    if (device.empty() || round + 1 >= options.containment_rounds || m.skeleton.centres.size() < 2) break;

    t0 = Clock::now();
    const geometry::TriangleMesh deformed{X.topRows(n), mesh.F};
    const geometry::RayCaster caster(deformed, geometry::RayCaster::BuildQuality::Low);
    // The deformed centerline runs through the planes, so its arc starts at the first one:
    // the radii are looked up by arc along it, plane by plane.
    const geometry::Polyline moved_centerline = deformed_centerline(m, deformed.V);
    const RadiusProfile moved_radius{geometry::arc_lengths(moved_centerline), m.skeleton.radius_mm};
    const auto more = select_control_points(deformed, caster, moved_centerline, moved_radius, device, control,
                                            in_other_lumen, entry);
    std::set<int> fresh;  // vertices constrained for the first time this round
    for (const auto& [v, p] : handle_vertex_targets(deformed, more))
      if (targets.emplace(v, p).second) fresh.insert(v);
    // Count only handles that constrain something new (the others were there already).
    for (const auto& h : more)
      if (fresh.count(mesh.F(h.face, 0)) || fresh.count(mesh.F(h.face, 1)) || fresh.count(mesh.F(h.face, 2)))
        ++report.control_points;
    report.timings.control_points_ms += ms_since(t0);
    if (fresh.empty()) break;
  }
  return X.topRows(n);
}

// The previous frame's vertices of vessel i, when that frame solved for it.
const geometry::Vertices* warm_start(const SceneDeformation* previous, std::size_t i) {
  if (!previous || previous->reports[i].iterations == 0) return nullptr;
  return &previous->vessels[i].mesh.V;
}

void check_device(const geometry::Polyline& device) {
  if (device.size() < 2) throw base::InputError("device: the curve has " + std::to_string(device.size()) +
                                                    " point(s); at least 2 are needed");
  for (std::size_t i = 0; i < device.size(); ++i)
    if (!device[i].allFinite()) throw base::InputError("device: point " + std::to_string(i) + " is not finite");
  const double length = geometry::arc_lengths(device).back();
  if (length <= 0.0) throw base::InputError("device: all points coincide");
  // Guidewires are at most a few metres long; more means a stray control point.
  if (length > 1e4)
    throw base::InputError("device: the curve is " + std::to_string(length) +
                               " mm long; at most 10000 mm is plausible (a stray control point?)");
}

}  // namespace

namespace {

// Keeps the faces of `faces` that touch no erased vertex of `dv` (vertices keep their
// order) and reports what went and how far the kept vertices moved from `rest`.
void apply_erasure(DeformedVessel& dv, const geometry::Faces& faces, const geometry::Vertices& rest, VesselReport& r) {
  geometry::Faces F(faces.rows(), 3);
  int kept = 0;
  for (Eigen::Index f = 0; f < faces.rows(); ++f)
    if (!dv.erased[static_cast<std::size_t>(faces(f, 0))] && !dv.erased[static_cast<std::size_t>(faces(f, 1))] &&
        !dv.erased[static_cast<std::size_t>(faces(f, 2))])
      F.row(kept++) = faces.row(f);
  dv.mesh.F = F.topRows(kept);
  r.erased_faces = static_cast<int>(faces.rows()) - kept;
  r.erased_vertices = static_cast<int>(std::count(dv.erased.begin(), dv.erased.end(), 1));
  r.max_displacement_mm = (dv.mesh.V - rest).rowwise().norm().maxCoeff();
}

// The scene with a proxy in place of every mesh that needs one (null when none does); a
// mesh whose proxy cannot be made is solved as it is.
std::unique_ptr<geometry::Scene> proxied(const geometry::Scene& scene, double edge_mm,
                                         std::vector<std::optional<MeshProxy>>& proxies,
                                         std::vector<std::string>& refusals, double& ms) {
  const auto t0 = Clock::now();
  proxies.assign(scene.vessels.size(), std::nullopt);
  refusals.assign(scene.vessels.size(), std::string());
  std::unique_ptr<geometry::Scene> working;
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    if (!needs_proxy(scene.vessels[i].mesh.mesh, edge_mm)) continue;
    try {
      proxies[i] = make_proxy(scene.vessels[i].mesh.mesh, edge_mm);
    } catch (const std::runtime_error& e) {
      refusals[i] = e.what();
      continue;
    }
    if (!working) working = std::make_unique<geometry::Scene>(scene);
    working->vessels[i].mesh.mesh = proxies[i]->coarse;
  }
  ms = ms_since(t0);
  return working;
}

}  // namespace

SceneDeformer::SceneDeformer(const geometry::Scene& original, DeformOptions options)
    : original_(original),
      options_(std::move(options)),
      working_(proxied(original, options_.proxy_edge_mm, proxies_, proxy_refusals_, proxy_ms_)),
      scene_(working_ ? *working_ : original) {
  const auto t0 = Clock::now();
  const geometry::Scene& scene = scene_;
  options_.control.device_thickness_mm = scene.device_thickness_mm;
  if (!(options_.coarse_knot_spacing_mm >= 0.0) || !std::isfinite(options_.coarse_knot_spacing_mm))
    throw std::invalid_argument("deform options: coarse_knot_spacing_mm must be 0 (none) or a positive length");
  if (std::none_of(scene.vessels.begin(), scene.vessels.end(),
                   [](const geometry::Vessel& v) { return v.kind == geometry::VesselKind::Aorta; }))
    throw base::InputError(scene.file.string() + ": the scene has no vessel of kind \"aorta\"");
  const auto& aorta = *std::find_if(scene.vessels.begin(), scene.vessels.end(),
                                    [](const geometry::Vessel& v) { return v.kind == geometry::VesselKind::Aorta; });
  // Where each iliac begins, against the aortic lumen (a closed aortic mesh has one).
  std::optional<geometry::RayCaster> aortic_lumen;
  if (geometry::is_closed(aorta.mesh.mesh))
    aortic_lumen.emplace(aorta.mesh.mesh, geometry::RayCaster::BuildQuality::Low);
  for (const auto& v : scene.vessels) {
    // Iliac centerlines run from the bifurcation (near the aorta) to the distal end; a
    // reversed one would bind the wrong end to the aorta.
    if (v.kind == geometry::VesselKind::Iliac &&
        geometry::project_onto(aorta.centerline, v.centerline.front()).distance_mm >
            geometry::project_onto(aorta.centerline, v.centerline.back()).distance_mm)
      throw base::InputError(v.centerline_path.string() + ": the centerline of iliac '" + v.name +
                                 "' runs toward the aorta; it must run from the bifurcation to the distal end");
    models_.push_back(make_model(v, options_));
    if (v.kind == geometry::VesselKind::Iliac) {
      // Its top is bound to the aortic wall: an iliac that begins well outside the aorta
      // (a gap between the meshes, or another frame) would be bound to a wall it never met.
      const Eigen::Vector3d start = v.centerline.front();
      const double gap = geometry::closest_point_on_mesh(aorta.mesh.mesh, start).distance_mm;
      const double allowed = models_.back()->radius.at(0.0) + 5.0;
      if (aortic_lumen && !aortic_lumen->contains(start) && gap > allowed) {
        char text[64];
        std::snprintf(text, sizeof text, "%.1f mm (at most %.1f)", gap, allowed);
        throw base::InputError(v.centerline_path.string() + ": iliac '" + v.name + "' begins " + text +
                                   " outside the aorta " + aorta.mesh_path.string() +
                                   "; its centerline must start at the bifurcation, inside or at the aortic wall");
      }
      bind_junction(*models_.back(), aorta.mesh.mesh, options_.bind_length_mm);
    }
    // The tethered system's own factor does not depend on the device either: made here, it
    // is not paid by the first device pose (measured: a third of the node's first model).
    models_.back()->system->prefactored();
  }
  // Each landmark follows the vessel surface it sits on, bound once here; one far from
  // every wall is in the wrong frame.
  for (const auto& lm : scene.landmarks) {
    LandmarkBinding lb;
    double nearest_mm = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
      lb.on.push_back(bind_to_surface(scene.vessels[i].mesh.mesh, lm.position_lps));
      if (lb.on.back().distance_mm < nearest_mm) nearest_mm = lb.on.back().distance_mm, lb.vessel = i;
    }
    if (nearest_mm > kMaxLandmarkDistanceMm)
      throw base::InputError(scene.landmarks_path.string() + ": landmark '" + lm.label + "' is " +
                                 std::to_string(nearest_mm) + " mm from the nearest vessel surface (at most " +
                                 std::to_string(kMaxLandmarkDistanceMm) + " mm expected)");
    landmark_bindings_.push_back(std::move(lb));
  }
  precompute_ms_ = proxy_ms_ + ms_since(t0);
}

SceneDeformer::~SceneDeformer() = default;

double SceneDeformer::lumen_radius_mm(std::size_t vessel, double arc_length_mm) const {
  return models_.at(vessel)->radius.at(arc_length_mm);
}

SceneDeformation deform_scene(const geometry::Scene& scene, const geometry::Polyline& device, const DeformOptions& options) {
  const SceneDeformer deformer(scene, options);
  SceneDeformation out = deformer.deform(device);
  out.total_ms += deformer.precompute_ms();
  return out;
}

SceneDeformation SceneDeformer::deform(const geometry::Polyline& device, const SceneDeformation* previous) const {
  if (!working_) {
    SceneDeformation out = solve(device, previous);
    for (std::size_t i = 0; i < out.reports.size(); ++i) out.reports[i].proxy_refused = proxy_refusals_[i];
    return out;
  }
  const auto t_total = Clock::now();
  // The previous frame as the proxies saw it.
  std::optional<SceneDeformation> seen;
  if (previous) {
    if (previous->vessels.size() != original_.vessels.size() || previous->proxy_solutions.size() != original_.vessels.size() ||
        previous->reports.size() != original_.vessels.size())
      throw std::invalid_argument("deform: the previous frame's deformation is of another scene");
    seen.emplace();
    seen->reports = previous->reports;
    seen->vessels.resize(previous->vessels.size());
    for (std::size_t i = 0; i < previous->vessels.size(); ++i)
      seen->vessels[i].mesh.V = proxies_[i] ? previous->proxy_solutions[i] : previous->vessels[i].mesh.V;
  }
  SceneDeformation out = solve(device, seen ? &*seen : nullptr);
  // The fine meshes follow their proxies; a fine vertex is erased with the proxy vertices
  // around it (by its barycentric weights).
  out.proxy_solutions.resize(out.vessels.size());
  for (std::size_t i = 0; i < out.vessels.size(); ++i) {
    out.reports[i].proxy_refused = proxy_refusals_[i];
    if (!proxies_[i]) continue;
    const MeshProxy& proxy = *proxies_[i];
    const geometry::TriangleMesh& fine = original_.vessels[i].mesh.mesh;
    DeformedVessel& dv = out.vessels[i];
    VesselReport& r = out.reports[i];
    out.proxy_solutions[i] = dv.mesh.V;
    DeformedVessel followed;
    followed.mesh.V = follow_proxy(proxy, dv.mesh.V);
    followed.erased.assign(static_cast<std::size_t>(fine.V.rows()), 0);
    for (std::size_t k = 0; k < proxy.bindings.size(); ++k) {
      const ProxyBinding& b = proxy.bindings[k];
      double weight = 0.0;
      for (int j = 0; j < 3; ++j) weight += b.barycentric[j] * dv.erased[static_cast<std::size_t>(proxy.coarse.F(b.face, j))];
      followed.erased[k] = weight >= 0.5 ? 1 : 0;
    }
    apply_erasure(followed, fine.F, fine.V, r);
    r.proxy_vertices = r.vertices;
    r.vertices = static_cast<int>(fine.V.rows());
    r.faces = static_cast<int>(fine.F.rows());
    dv = std::move(followed);
  }
  out.total_ms = ms_since(t_total);
  return out;
}

SceneDeformation SceneDeformer::solve(const geometry::Polyline& device, const SceneDeformation* previous) const {
  const auto t_total = Clock::now();
  check_device(device);
  if (previous) {
    bool same = previous->vessels.size() == scene_.vessels.size() && previous->reports.size() == scene_.vessels.size();
    for (std::size_t i = 0; same && i < scene_.vessels.size(); ++i)
      same = previous->vessels[i].mesh.V.rows() == scene_.vessels[i].mesh.mesh.V.rows();
    if (!same) throw std::invalid_argument("deform: the previous frame's deformation is of another scene");
  }
  const geometry::Scene& scene = scene_;
  const DeformOptions& options = options_;
  const auto& models = models_;
  std::vector<int> device_points(models.size(), 0);
  for (std::size_t i = 0; i < models.size(); ++i)
    device_points[i] = static_cast<int>(
        device_points_in_vessel(models[i]->vessel->centerline, models[i]->radius, device, options.control).size());

  SceneDeformation out;
  out.reports.resize(scene.vessels.size());
  out.vessels.resize(scene.vessels.size());
  int aorta = -1, device_iliac = -1;
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    const auto& v = scene.vessels[i];
    auto& r = out.reports[i];
    r.name = v.name;
    r.kind = geometry::to_string(v.kind);
    r.role = "unchanged";
    r.vertices = static_cast<int>(v.mesh.mesh.V.rows());
    r.faces = static_cast<int>(v.mesh.mesh.F.rows());
    r.device_points = device_points[i];
    r.timings.skeleton_ms = models[i]->skeleton_ms;
    r.timings.weights_ms = models[i]->weights_ms;
    out.vessels[i].mesh = v.mesh.mesh;
    out.vessels[i].erased.assign(static_cast<std::size_t>(r.vertices), 0);
    if (v.kind == geometry::VesselKind::Aorta && aorta < 0) aorta = static_cast<int>(i);
    // The iliac carrying the device is the one holding most of it.
    if (v.kind == geometry::VesselKind::Iliac && device_points[i] > 0 &&
        (device_iliac < 0 || device_points[i] > device_points[static_cast<std::size_t>(device_iliac)]))
      device_iliac = static_cast<int>(i);
  }
  if (std::accumulate(device_points.begin(), device_points.end(), 0) == 0) {
    double nearest = std::numeric_limits<double>::infinity();
    std::string which;
    for (const auto& m : models)
      for (const auto& d : device) {
        const double dist = geometry::project_onto(m->vessel->centerline, d).distance_mm;
        if (dist < nearest) nearest = dist, which = m->vessel->name;
      }
    char approach[32];
    std::snprintf(approach, sizeof approach, "%.1f", nearest);
    throw base::InputError("device: no part of the device lies in any vessel (closest approach " +
                               std::string(approach) + " mm to the centerline of '" + which +
                               "'); check where the device came from (its file, or the views and C-arm "
                               "geometry it was reconstructed from) and the CT to C-arm registration");
  }

  // Device points inside another vessel's preoperative lumen are that vessel's: where the
  // aorta's lumen runs on into an iliac, the device leaves one wall without pushing it. A
  // closed mesh's inside is told by ray parity; an open one (its ends cut off, as
  // segmentations often leave them) has none, so its lumen is its radius profile around
  // its centerline.
  const auto in_lumen = [](const VesselModel& m, const Eigen::Vector3d& p) {
    if (m.closed) return m.caster->contains(p);
    const auto at = geometry::project_onto(m.vessel->centerline, p);
    return !at.beyond_start && !at.beyond_end && at.distance_mm < m.radius.at(at.arc_length_mm);
  };
  const auto in_other_lumen = [&models, &in_lumen](std::size_t i) -> LumenTest {
    return [&models, &in_lumen, i](const Eigen::Vector3d& p) {
      for (std::size_t j = 0; j < models.size(); ++j)
        if (j != i && in_lumen(*models[j], p)) return true;
      return false;
    };
  };

  // 1. Aorta.
  const auto& aorta_mesh = scene.vessels[static_cast<std::size_t>(aorta)].mesh.mesh;
  auto& aorta_report = out.reports[static_cast<std::size_t>(aorta)];
  {
    const auto& m = *models[static_cast<std::size_t>(aorta)];
    out.vessels[static_cast<std::size_t>(aorta)].mesh.V =
        deform_vessel(m, device, {}, options, in_other_lumen(static_cast<std::size_t>(aorta)),
                      warm_start(previous, static_cast<std::size_t>(aorta)), aorta_report);
    if (aorta_report.control_points > 0) aorta_report.role = "deformed";
  }
  const auto& aorta_deformed = out.vessels[static_cast<std::size_t>(aorta)].mesh.V;

  // 2-4. Iliacs. Each depends on the deformed aorta only, not on the others (the carrier
  // alone writes the aorta's erasure), so with more than one they are solved at once.
  const auto solve_iliac = [&](std::size_t i) {
    const auto& v = scene.vessels[i];
    auto& r = out.reports[i];
    const auto& m = *models[i];
    const auto& mesh = v.mesh.mesh;
    const auto t0 = Clock::now();
    // The top vertices move as the aortic surface where they are bound.
    std::map<int, Eigen::Vector3d> bound;
    bool junction_moved = false;
    for (const auto& [k, at] : m.junction) {
      Eigen::Vector3d shift = Eigen::Vector3d::Zero();
      for (int j = 0; j < 3; ++j) {
        const int a = aorta_mesh.F(at.face, j);
        shift += at.barycentric[j] * (aorta_deformed.row(a) - aorta_mesh.V.row(a)).transpose();
      }
      bound[k] = mesh.V.row(k).transpose() + shift;
      junction_moved = junction_moved || shift.norm() > 0.0;
    }
    r.bound_vertices = static_cast<int>(bound.size());
    r.junction_gap_mm = m.junction_gap_mm;
    r.timings.control_points_ms = ms_since(t0);
    const bool carries = static_cast<int>(i) == device_iliac;
    if (carries && bound.empty())
      throw base::InputError(v.mesh_path.string() + ": no vertex of iliac '" + v.name + "' lies within " +
                                 std::to_string(options.bind_length_mm) +
                                 " mm of its centerline's proximal end, so it cannot be bound to the aorta");
    auto& V_out = out.vessels[i].mesh.V;
    if (carries) {
      // Solved once, with the handles the device gives (none where it runs inside the
      // lumen: then the junction alone moves it), and the stump it replaces erased either
      // way, so the erasure does not come and go from one frame of a live sequence to the next.
      V_out = deform_vessel(m, device, bound, options, in_other_lumen(i), warm_start(previous, i), r);
      r.role = "carries the device";
      // 3. Erase the aortic vertices below the bound iliac points: distal of the plane
      // through their centroid (normal: the iliac's initial direction) and inside the
      // deformed iliac, i.e. the part of the aorta the iliac now represents. For an open
      // iliac mesh (no inside) the test is the iliac's top radius around its axis.
      const auto arc = geometry::arc_lengths(v.centerline);
      const Eigen::Vector3d axis = geometry::tangent_at(v.centerline, arc, 0.0);
      const double cut_radius = m.radius.at(0.0);
      const geometry::TriangleMesh deformed_iliac{V_out, mesh.F};
      const std::optional<geometry::RayCaster> inside =
          m.closed ? std::optional<geometry::RayCaster>(std::in_place, deformed_iliac, geometry::RayCaster::BuildQuality::Low)
                 : std::nullopt;
      auto& erased = out.vessels[static_cast<std::size_t>(aorta)].erased;
      for (Eigen::Index k = 0; k < aorta_mesh.V.rows(); ++k) {
        const Eigen::Vector3d q = aorta_mesh.V.row(k).transpose() - m.top_centroid;
        const double along = q.dot(axis);
        if (along <= 0.0) continue;
        const bool within = inside ? inside->contains(aorta_deformed.row(k).transpose())
                                   : (q - along * axis).norm() < cut_radius;
        if (within) erased[static_cast<std::size_t>(k)] = 1;
      }
    } else if (junction_moved) {
      // 4. No device: the junction moves with the aorta and the rest of the iliac bends
      // after it by ARAP, held toward its registered pose by the tether as the distal
      // iliac is by the inguinal ligament and the femoral access (no device handles: the
      // paper deforms this iliac by nothing; a rigid follow would swing its distal part).
      V_out = deform_vessel(m, {}, bound, options, {}, warm_start(previous, i), r);
      r.role = "follows the aorta";
    }
  };
  std::vector<std::size_t> iliacs;
  for (std::size_t i = 0; i < scene.vessels.size(); ++i)
    if (scene.vessels[i].kind == geometry::VesselKind::Iliac) iliacs.push_back(i);
  // All but the last on threads of their own, the last here; every one is waited for, and
  // the first failure in scene order is the one reported, as one after the other would.
  std::vector<std::future<void>> others;
  for (std::size_t k = 0; k + 1 < iliacs.size(); ++k)
    others.push_back(std::async(options.parallel_iliacs ? std::launch::async : std::launch::deferred, solve_iliac, iliacs[k]));
  std::vector<std::exception_ptr> failed(iliacs.size());
  if (!iliacs.empty()) try {
      solve_iliac(iliacs.back());
    } catch (...) {
      failed.back() = std::current_exception();
    }
  for (std::size_t k = 0; k < others.size(); ++k) try {
      others[k].get();
    } catch (...) {
      failed[k] = std::current_exception();
    }
  for (const auto& e : failed)
    if (e) std::rethrow_exception(e);

  // Apply erasures: faces touching an erased vertex are removed; vertices keep their order.
  for (std::size_t i = 0; i < out.vessels.size(); ++i) {
    const geometry::Faces faces = out.vessels[i].mesh.F;  // a copy: apply_erasure replaces them
    apply_erasure(out.vessels[i], faces, scene.vessels[i].mesh.mesh.V, out.reports[i]);
  }

  // 5. Landmarks follow the surface they were bound to; one on the erased aortic stump
  // follows the carrier iliac, which now represents that part of the aorta (the stump's
  // vertices were solved with nothing inside them to hold).
  for (std::size_t k = 0; k < scene.landmarks.size(); ++k) {
    const auto& lb = landmark_bindings_[k];
    std::size_t vessel = lb.vessel;
    if (device_iliac >= 0 && static_cast<int>(vessel) == aorta) {
      const auto& erased = out.vessels[vessel].erased;
      const auto& F = scene.vessels[vessel].mesh.mesh.F;
      const int f = lb.on[vessel].face;
      if (erased[static_cast<std::size_t>(F(f, 0))] || erased[static_cast<std::size_t>(F(f, 1))] ||
          erased[static_cast<std::size_t>(F(f, 2))])
        vessel = static_cast<std::size_t>(device_iliac);
    }
    out.landmarks.push_back({scene.landmarks[k].label, evaluate_binding(lb.on[vessel], scene.vessels[vessel].mesh.mesh.F,
                                                                        out.vessels[vessel].mesh.V)});
    out.landmark_vessel.push_back(scene.vessels[vessel].name);
  }
  if (device_iliac >= 0) out.device_iliac = scene.vessels[static_cast<std::size_t>(device_iliac)].name;
  for (auto& r : out.reports)
    r.timings.total_ms = r.timings.weights_ms + r.timings.control_points_ms + r.timings.skeleton_ms + r.timings.factor_ms +
                         r.timings.iterate_ms;
  out.total_ms = ms_since(t_total);
  return out;
}

}  // namespace evar::deform
