#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <set>

#include "evar/base/elapsed.hpp"
#include "evar/base/input_error.hpp"
#include "evar/deform/registration_tether.hpp"
#include "vessel_model.hpp"

namespace evar::deform::detail {

namespace {
using Clock = std::chrono::steady_clock;
using base::ms_since;

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

}  // namespace

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
  geometry::Vertices X;
  for (int round = 0;; ++round) {
    std::vector<int> constrained;
    geometry::Vertices rows(static_cast<Eigen::Index>(targets.size()), 3);
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

}  // namespace evar::deform::detail
