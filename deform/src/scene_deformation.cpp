#include "evar/deform/scene_deformation.hpp"

#include <Eigen/Geometry>
#include <chrono>
#include <exception>
#include <future>
#include <numeric>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>

#include "evar/deform/landmark_binding.hpp"
#include "evar/deform/mesh_proxy_file.hpp"
#include "evar/deform/registration_tether.hpp"
#include "evar/base/elapsed.hpp"
#include "evar/geometry/closest_point.hpp"
#include "evar/base/input_error.hpp"
#include "evar/base/quantity_text.hpp"
#include "vessel_model.hpp"

// The scene's solve, in the paper's order: the aorta first, then each iliac bound to it
// (the carrier with the device, the others following the junction), the aortic stump the
// carrier replaces erased, and the landmarks carried by their surfaces. What is made once
// per vessel is in vessel_model.cpp, one vessel's solve in vessel_solve.cpp, the stump's
// erasure in stump_erasure.cpp.
namespace evar::deform {
namespace {

using Clock = std::chrono::steady_clock;
using base::ms_since;
using detail::apply_erasure;
using detail::bind_junction;
using detail::deform_vessel;
using detail::make_model;
using detail::VesselModel;

// Ostium landmarks are placed on the wall; 10 mm off is already a different structure.
constexpr double kMaxLandmarkDistanceMm = 10.0;

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
    throw base::InputError("device: the curve is " + base::quantity_text(length, "mm") +
                               " long; at most 10000 mm is plausible (a stray control point?)");
}

// The scene with a proxy in place of every mesh that needs one (null when none does): read
// from the scene's proxy file where it names a usable one, made otherwise; a mesh whose
// proxy cannot be made is solved as it is.
std::unique_ptr<geometry::Scene> proxied(const geometry::Scene& scene, double edge_mm,
                                         std::vector<std::optional<MeshProxy>>& proxies,
                                         std::vector<std::string>& refusals,
                                         std::vector<SceneDeformer::ProxyOrigin>& origins, double& ms) {
  const auto t0 = Clock::now();
  proxies.assign(scene.vessels.size(), std::nullopt);
  refusals.assign(scene.vessels.size(), std::string());
  origins.assign(scene.vessels.size(), {});
  std::unique_ptr<geometry::Scene> working;
  for (std::size_t i = 0; i < scene.vessels.size(); ++i) {
    const auto& vessel = scene.vessels[i];
    if (!needs_proxy(vessel.mesh.mesh, edge_mm)) continue;
    if (!vessel.proxy_path.empty()) {
      try {
        proxies[i] = read_mesh_proxy(vessel.proxy_path, vessel.mesh.mesh, edge_mm);
        origins[i].file = vessel.proxy_path.string();
      } catch (const std::exception& e) {  // a cache: whatever is wrong with it, the proxy is made anew
        origins[i].unused = e.what();
      }
    }
    if (!proxies[i]) {
      try {
        proxies[i] = make_proxy_or_finer(vessel.mesh.mesh, edge_mm);
      } catch (const std::runtime_error& e) {
        refusals[i] = e.what();
        continue;
      }
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
      working_(proxied(original, options_.proxy_edge_mm, proxies_, proxy_refusals_, proxy_origins_, proxy_ms_)),
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
                                 base::quantity_text(nearest_mm, "mm") + " from the nearest vessel surface (at most " +
                                 base::quantity_text(kMaxLandmarkDistanceMm, "mm") + " expected): is it in the scene's coordinates (LPS)?");
    landmark_bindings_.push_back(std::move(lb));
  }
  // The fine meshes' vertices past their centerline's ends (within a quarter millimetre of
  // an end counts: a cap lies in the plane square to the centerline at its end).
  constexpr double kAtTheEndMm = 0.25;
  for (const auto& v : original_.vessels) {
    const geometry::PolylineProjector onto(v.centerline);
    const double length = geometry::arc_lengths(v.centerline).back();
    std::vector<char> past(static_cast<std::size_t>(v.mesh.mesh.V.rows()), 0);
    int segment = -1;
    for (Eigen::Index k = 0; k < v.mesh.mesh.V.rows(); ++k) {
      const auto at = onto.project(v.mesh.mesh.V.row(k).transpose(), segment, &segment);
      past[static_cast<std::size_t>(k)] = at.beyond_start || at.beyond_end || at.arc_length_mm < kAtTheEndMm ||
                                          at.arc_length_mm > length - kAtTheEndMm;
    }
    past_centerline_ends_.push_back(std::move(past));
    // Which way the faces wind: the area-weighted vote of their normals against the
    // direction away from the centerline, over about 2000 faces spread over the mesh (a
    // vote needs no more).
    double outward = 0.0;
    const auto& V = v.mesh.mesh.V;
    const auto& F = v.mesh.mesh.F;
    const Eigen::Index stride = std::max<Eigen::Index>(1, F.rows() / 2000);
    segment = -1;
    for (Eigen::Index f = 0; f < F.rows(); f += stride) {
      const Eigen::Vector3d a = V.row(F(f, 0)).transpose(), b = V.row(F(f, 1)).transpose(), c = V.row(F(f, 2)).transpose();
      const Eigen::Vector3d centroid = (a + b + c) / 3.0;
      const auto at = onto.project(centroid, segment, &segment);
      outward += (b - a).cross(c - a).dot(centroid - at.point);
    }
    wound_inward_.push_back(outward < 0.0 ? 1 : 0);
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
  out.precompute_ms = deformer.precompute_ms();
  out.proxy_ms = deformer.proxy_ms();
  out.total_ms += deformer.precompute_ms();
  return out;
}

SceneDeformation SceneDeformer::deform(const geometry::Polyline& device, const SceneDeformation* previous) const {
  const auto t_total = Clock::now();
  SceneDeformation out = deform_vessels(device, previous);
  // 6. The device against the result, the faces touching the mesh past its centerline's
  // ends marked as caps.
  const auto t_containment = Clock::now();
  std::vector<geometry::TriangleMesh> walls(out.vessels.size());
  std::vector<NamedSurface> surfaces;
  for (std::size_t i = 0; i < out.vessels.size(); ++i) {
    const auto& mesh = out.vessels[i].mesh;
    const auto& past = past_centerline_ends_[i];
    walls[i].V = mesh.V;
    walls[i].F = mesh.F;
    if (wound_inward_[i]) walls[i].F.col(1).swap(walls[i].F.col(2));
    std::vector<char> caps(static_cast<std::size_t>(mesh.F.rows()), 0);
    for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
      caps[static_cast<std::size_t>(f)] = past[static_cast<std::size_t>(mesh.F(f, 0))] ||
                                          past[static_cast<std::size_t>(mesh.F(f, 1))] ||
                                          past[static_cast<std::size_t>(mesh.F(f, 2))];
    surfaces.push_back({original_.vessels[i].name, &walls[i], &original_.vessels[i].centerline, std::move(caps)});
  }
  out.containment = measure_device_containment(surfaces, device);
  out.containment_ms = ms_since(t_containment);
  out.total_ms = ms_since(t_total);
  return out;
}

SceneDeformation SceneDeformer::deform_vessels(const geometry::Polyline& device, const SceneDeformation* previous) const {
  if (!working_) {
    SceneDeformation out = solve(device, previous);
    for (std::size_t i = 0; i < out.reports.size(); ++i) {
      out.reports[i].proxy_refused = proxy_refusals_[i];
      out.reports[i].proxy_file_unused = proxy_origins_[i].unused;
    }
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
    out.reports[i].proxy_file = proxy_origins_[i].file;
    out.reports[i].proxy_file_unused = proxy_origins_[i].unused;
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
    r.proxy_edge_mm = proxy.edge_mm;
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
      throw base::InputError(
          v.mesh_path.string() + ": no vertex of iliac '" + v.name + "' lies within " +
          base::quantity_text(options.bind_length_mm, "mm") + " (along its centerline) of the centerline's proximal end, "
          "so its top cannot be bound to the aorta: the mesh begins " + base::quantity_text(m.mesh_begins_at_mm, "mm", 1) +
          " along the centerline (its nearest vertex is " + base::quantity_text(m.nearest_vertex_to_start_mm, "mm", 1) +
          " from the start). Start the centerline " + v.centerline_path.filename().string() +
          " where the mesh begins, at the bifurcation, or let `evarnode scene` cut the surface and trim the centerlines");
    auto& V_out = out.vessels[i].mesh.V;
    if (carries) {
      // Solved once, with the handles the device gives (none where it runs inside the
      // lumen: then the junction alone moves it), and the stump it replaces erased either
      // way, so the erasure does not come and go from one frame of a live sequence to the next.
      V_out = deform_vessel(m, device, bound, options, in_other_lumen(i), warm_start(previous, i), r);
      r.role = "carries the device";
      // 3. Erase the aortic stump the carrier now represents.
      detail::mark_aortic_stump(m, V_out, aorta_mesh, aorta_deformed, out.vessels[static_cast<std::size_t>(aorta)].erased);
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
