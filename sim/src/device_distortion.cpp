#include "evar/sim/device_distortion.hpp"

#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>

#include "evar/geometry/closest_point.hpp"
#include "evar/sim/tube_mesh.hpp"
#include "section_sweep.hpp"
#include "truth_checks.hpp"

namespace evar::sim {
namespace {

using geometry::Polyline;

// Is x inside the tube of radii `radii` (per point, along the rest arc lengths `arc`)
// around `centerline` (moved; `length_mm` its length), by at least `margin`?
bool inside_tube(const Polyline& centerline, double length_mm, const std::vector<double>& arc,
                 const std::vector<double>& radii, const Eigen::Vector3d& x, double margin) {
  const auto proj = geometry::project_onto(centerline, x);
  if (proj.beyond_start || proj.beyond_end) return false;
  const double s = proj.arc_length_mm * arc.back() / length_mm;  // back to rest arc
  return proj.distance_mm <= interpolate_along(arc, radii, s) - margin;
}

// Elastic beams through centerline points (1 mm apart, nearly), several chains in one
// system: per node its rest position, lumen radius and bending λ. solve() minimizes
//   Σ λ_i |u_{i-1} - 2u_i + u_{i+1}|²  (within a chain)  + Σ |u_i|²  (tissue)
//   + Σ_pins w |u_i|² + Σ_ties w |u_i - (1-f) u_a - f u_b|²
//   + Σ 4λ/r² (t_i·(u_{i+1} - u_i))²  (axial)  + Σ_contacts λ |u_i - g_i|².
struct Beams {
  std::vector<Eigen::Vector3d> rest;
  std::vector<double> radius, bending;
  std::vector<char> chain_start;  // first node of a chain (no bending across it)
  std::vector<char> pushed;       // the device may push this section
  std::vector<char> active;       // in contact
  std::vector<Eigen::Vector3d> target;  // wanted displacement where active
  std::vector<std::size_t> pins;        // nodes held at zero displacement
  struct Tie {
    std::size_t node, a, b;
    double f;
  };
  std::vector<Tie> ties;
  double pin_weight = 0.0;  // for pins and ties: stiff against every bending in the system

  std::size_t add_chain(const ExampleVessel& v, const std::vector<double>& lambda, const std::vector<char>& push) {
    const std::size_t first = rest.size();
    for (std::size_t i = 0; i < v.centerline.size(); ++i) {
      rest.push_back(v.centerline[i]);
      radius.push_back(v.radii_mm[i]);
      bending.push_back(lambda[i]);
      chain_start.push_back(i == 0 ? 1 : 0);
      pushed.push_back(push[i]);
      active.push_back(0);
      target.emplace_back(Eigen::Vector3d::Zero());
    }
    return first;
  }

  Eigen::MatrixX3d solve() const {
    const auto n = static_cast<Eigen::Index>(rest.size());
    std::vector<Eigen::Triplet<double>> T;
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(3 * n);
    const auto at = [](std::size_t i) { return static_cast<Eigen::Index>(i); };
    // An isotropic term adds the same scalar to the x, y and z blocks.
    const auto iso = [&](Eigen::Index r, Eigen::Index c, double v) {
      for (Eigen::Index d = 0; d < 3; ++d) T.emplace_back(3 * r + d, 3 * c + d, v);
    };
    for (std::size_t i = 0; i < rest.size(); ++i) {
      iso(at(i), at(i), 1.0);  // surrounding tissue
      // Axial stiffness of the segment i, i+1 (linearized inextensibility): a tube's
      // EA = 4 EI / r², so 4λ/r² (t·(u_{i+1} - u_i))². Without it, pushes across a bend
      // would shorten the vessel like an accordion.
      if (i + 1 < rest.size() && !chain_start[i + 1]) {
        const Eigen::Vector3d t = (rest[i + 1] - rest[i]).normalized();
        const double w = 4.0 * bending[i] / (radius[i] * radius[i]);
        const Eigen::Matrix3d K = w * t * t.transpose();
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) {
            T.emplace_back(3 * at(i) + r, 3 * at(i) + c, K(r, c));
            T.emplace_back(3 * at(i + 1) + r, 3 * at(i + 1) + c, K(r, c));
            T.emplace_back(3 * at(i) + r, 3 * at(i + 1) + c, -K(r, c));
            T.emplace_back(3 * at(i + 1) + r, 3 * at(i) + c, -K(r, c));
          }
      }
      if (i == 0 || i + 1 == rest.size() || chain_start[i] || chain_start[i + 1]) continue;
      const Eigen::Index idx[3] = {at(i - 1), at(i), at(i + 1)};
      const double coef[3] = {1.0, -2.0, 1.0};
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) iso(idx[a], idx[b], bending[i] * coef[a] * coef[b]);
    }
    for (const std::size_t i : pins) iso(at(i), at(i), pin_weight);
    for (const Tie& t : ties) {
      const Eigen::Index idx[3] = {at(t.node), at(t.a), at(t.b)};
      const double coef[3] = {1.0, -(1.0 - t.f), -t.f};
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) iso(idx[a], idx[b], pin_weight * coef[a] * coef[b]);
    }
    // A contact weighs as much as the beam's bending there, and its target moves on each
    // round until the section holds the device: bending spreads it instead of kinking.
    for (std::size_t i = 0; i < rest.size(); ++i)
      if (active[i]) {
        iso(at(i), at(i), bending[i]);
        rhs.segment<3>(3 * at(i)) += bending[i] * target[i];
      }
    Eigen::SparseMatrix<double> A(3 * n, 3 * n);
    A.setFromTriplets(T.begin(), T.end());
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(A);
    if (solver.info() != Eigen::Success) throw std::runtime_error("distort_by_device: beam system is singular");
    const Eigen::VectorXd x = solver.solve(rhs);
    Eigen::MatrixX3d u(n, 3);
    for (Eigen::Index i = 0; i < n; ++i) u.row(i) = x.segment<3>(3 * i).transpose();
    return u;
  }
};

double bending_of(const DistortionOptions& o, bool aorta, double arc_mm) {
  const double l = aorta ? o.aorta_bending_length_mm
                   : arc_mm < o.common_iliac_length_mm ? o.common_iliac_bending_length_mm
                                                       : o.external_iliac_bending_length_mm;
  return std::pow(l, 4);  // 1 mm spacing: λ = (l / h)^4
}

}  // namespace

geometry::TriangleMesh resweep(const geometry::TriangleMesh& mesh, const Polyline& centerline, const Polyline& moved) {
  return detail::SectionSweep(centerline, moved).map(mesh);
}

DeviceDistortion distort_by_device(const ExampleScene& scene, const DistortionOptions& o) {
  const detail::VesselRoles roles = detail::vessel_roles(scene, "distort_by_device");
  const ExampleVessel* aorta = &scene.vessels[roles.aorta];
  const ExampleVessel* carrier = &scene.vessels[roles.carrier];
  const auto aorta_arc = geometry::arc_lengths(aorta->centerline);
  const double hub_arc = roles.hub_arc_mm;

  // The bifurcation hub: the aorta below the highest iliac start and each iliac's overlap
  // inside the aortic lumen. It is made 100x stiffer in bending, so it moves nearly
  // rigidly and the bends spread over the vessels instead of kinking the junction, whose
  // sections are wider than such a bend's radius.
  constexpr double kHubStiffening = 100.0;
  if (!(hub_arc > 10.0)) throw std::invalid_argument("distort_by_device: the iliacs start too high in the aorta");

  Beams beams;
  std::vector<std::size_t> first(scene.vessels.size());
  std::vector<std::vector<double>> arcs(scene.vessels.size());
  for (std::size_t vi = 0; vi < scene.vessels.size(); ++vi) {
    const ExampleVessel& v = scene.vessels[vi];
    const bool is_aorta = &v == aorta;
    arcs[vi] = geometry::arc_lengths(v.centerline);
    const std::size_t overlap = roles.overlap[vi];
    std::vector<double> lambda;
    std::vector<char> push;
    for (std::size_t i = 0; i < v.centerline.size(); ++i) {
      const double s = arcs[vi][i];
      const bool in_hub = is_aorta ? s >= hub_arc : i < overlap;
      // Next to the hub (above it in the aorta, below the overlap in an iliac) the stiffness
      // ramps over two radii, so a push beside the stiff hub bends the vessel over a length
      // its sections can follow without folding.
      const double from_hub = is_aorta ? hub_arc - s : s - (overlap > 0 ? arcs[vi][overlap - 1] : 0.0);
      const double ramp = in_hub ? 1.0 : std::clamp(1.0 - from_hub / (2.0 * v.radii_mm[i]), 0.0, 1.0);
      lambda.push_back(bending_of(o, is_aorta, s) * std::pow(kHubStiffening, ramp));
      // The device pushes the aorta above the hub and the carrier below its overlap, except
      // the carrier's last millimetres: the access sheath keeps the device central there,
      // and a push next to the tethered end would only kink the beam.
      constexpr double kSheathMm = 3.0;
      push.push_back(!in_hub && (is_aorta || (&v == carrier && arcs[vi].back() - s >= kSheathMm)) ? 1 : 0);
    }
    first[vi] = beams.add_chain(v, lambda, push);
    // Tethers: the aortic top (visceral segment); an iliac's distal end (inguinal ligament).
    beams.pins.push_back(is_aorta ? first[vi] : first[vi] + v.centerline.size() - 1);
  }
  // Pins and ties 100x the stiffest bending: firm, while the system stays well within
  // double precision (tissue springs are 1).
  beams.pin_weight = 1e2 * *std::max_element(beams.bending.begin(), beams.bending.end());
  const std::size_t a0 = first[roles.aorta];
  const geometry::PolylineProjector aorta_projector(aorta->centerline);
  for (std::size_t vi = 0; vi < scene.vessels.size(); ++vi) {
    const ExampleVessel& v = scene.vessels[vi];
    if (&v == aorta) continue;
    const std::size_t overlap = roles.overlap[vi];
    for (std::size_t i = 0; i < overlap; ++i) {  // the overlap moves with the aorta around it
      int seg = 0;
      const auto proj = aorta_projector.project(v.centerline[i], -1, &seg);
      const auto j = static_cast<std::size_t>(seg);
      const double len = aorta_arc[j + 1] - aorta_arc[j];
      const double f = len > 0.0 ? std::clamp((proj.arc_length_mm - aorta_arc[j]) / len, 0.0, 1.0) : 0.0;
      beams.ties.push_back({first[vi] + i, a0 + j, a0 + j + 1, f});
    }
  }

  const double wall = 0.5 * scene.device_thickness_mm + o.clearance_mm;
  Eigen::MatrixX3d u = Eigen::MatrixX3d::Zero(static_cast<Eigen::Index>(beams.rest.size()), 3);
  const auto moved = [&](std::size_t vi) {
    Polyline c = scene.vessels[vi].centerline;
    for (std::size_t i = 0; i < c.size(); ++i) c[i] += u.row(static_cast<Eigen::Index>(first[vi] + i)).transpose();
    return c;
  };
  const std::size_t ai = roles.aorta;
  const std::size_t ci = roles.carrier;
  DeviceDistortion out;
  out.carrier = carrier->name;
  // The contact works on sections; the check is on the swept meshes. Where they disagree
  // (a tight bend, whose swept sections overlap), device points can lie outside the
  // meshes though every section holds the device: the section whose wall is nearest such a
  // point is then pushed past it, and the contact is solved again. Passes without such a
  // point change nothing, so most patients never need a second one.
  constexpr int kMeshPasses = 8;
  for (int pass = 0;; ++pass) {
    double intrusion = 0.0;
    for (int round = 0; round <= o.max_contact_rounds; ++round) {
      // Contact: sections the device crosses outside the lumen are pushed toward it, unless
      // the crossing lies in the other vessel (in the bifurcation the union of aorta and
      // carrier holds the device).
      const Polyline now[2] = {moved(ai), moved(ci)};
      const double now_length[2] = {geometry::arc_lengths(now[0]).back(), geometry::arc_lengths(now[1]).back()};
      intrusion = 0.0;
      bool changed = false;
      for (int side = 0; side < 2; ++side) {
        const std::size_t vi = side == 0 ? ai : ci, other = side == 0 ? ci : ai;
        const Polyline& c = now[side];
        for (std::size_t i = 1; i + 1 < c.size(); ++i) {
          const std::size_t k = first[vi] + i;
          if (!beams.pushed[k]) continue;
          // The section is the preoperative one translated (see detail::SectionSweep): its plane
          // keeps the preoperative normal.
          const Eigen::Vector3d t = (beams.rest[k + 1] - beams.rest[k - 1]).normalized();
          const auto x = detail::device_crossing(scene.device, c[i], t, beams.radius[k] + 15.0);
          if (!x) continue;
          const Eigen::Vector3d e = *x - c[i];
          const double over = e.norm() - (beams.radius[k] - wall);
          if (over <= 0.0 || inside_tube(now[1 - side], now_length[1 - side], arcs[other], scene.vessels[other].radii_mm, *x, wall)) continue;
          intrusion = std::max(intrusion, over);
          if (over <= 0.005) continue;
          // Aim slightly past the wall so the active set closes from the safe side.
          const Eigen::Vector3d from = beams.active[k] ? beams.target[k] : Eigen::Vector3d(u.row(static_cast<Eigen::Index>(k)).transpose());
          beams.target[k] = from + (over + 0.02) * e.normalized();
          beams.active[k] = 1;
          changed = true;
        }
      }
      out.rounds += round > 0 ? 1 : 0;
      if (!changed) break;
      if (round == o.max_contact_rounds)
        throw std::runtime_error("distort_by_device: contact did not converge in " + std::to_string(round) +
                                 " rounds (intrusion " + std::to_string(intrusion) + " mm)");
      u = beams.solve();
    }
    out.max_intrusion_mm = intrusion;

    out.vessels.clear();
    for (std::size_t vi = 0; vi < scene.vessels.size(); ++vi) {
      const ExampleVessel& v = scene.vessels[vi];
      VesselDistortion vd;
      vd.name = v.name;
      vd.centerline = moved(vi);
      for (std::size_t i = 0; i < vd.centerline.size(); ++i) {
        vd.max_displacement_mm = std::max(vd.max_displacement_mm, (vd.centerline[i] - v.centerline[i]).norm());
        vd.contact_sections += beams.active[first[vi] + i];
      }
      vd.mesh = resweep(v.mesh, v.centerline, vd.centerline);
      out.vessels.push_back(std::move(vd));
    }

    // Check the result on the meshes themselves: every device point inside the union of the
    // distorted vessels (ray parity) or within Δd of a wall.
    const auto outside = detail::device_outside(scene.device, out.vessels, scene.device_thickness_mm);
    detail::record_outside(outside, out);
    bool pushed_more = false;
    // The section that carries each such wall point moves toward the device point, past it
    // by the device's half thickness and the clearance.
    for (const auto& o : outside) {
      if (pass == kMeshPasses) break;
      const auto proj = geometry::project_onto(out.vessels[o.vessel].centerline, o.wall_point);
      const auto& arc = geometry::arc_lengths(out.vessels[o.vessel].centerline);
      const std::size_t i = static_cast<std::size_t>(
          std::lower_bound(arc.begin(), arc.end(), proj.arc_length_mm) - arc.begin());
      const std::size_t node = first[o.vessel] + std::min(i, arc.size() - 1);
      if (!beams.pushed[node]) continue;
      const Eigen::Vector3d from = beams.active[node] ? beams.target[node] : Eigen::Vector3d(u.row(static_cast<Eigen::Index>(node)).transpose());
      beams.target[node] = from + (o.gap_mm + wall + 0.02) * (scene.device[o.point] - o.wall_point).normalized();
      beams.active[node] = 1;
      pushed_more = true;
    }
    if (!pushed_more) break;
    out.mesh_passes = pass + 1;
    u = beams.solve();
  }

  // A landmark moves with the vessel whose wall it sits on (|distance to centerline - radius| least).
  for (const auto& lm : scene.landmarks) {
    const std::size_t best = detail::wall_vessel(scene.vessels, lm.position_lps);
    const detail::SectionSweep sweep(scene.vessels[best].centerline, out.vessels[best].centerline);
    int hint = -1;
    out.landmarks.push_back({lm.label, sweep.map(lm.position_lps, &hint)});
  }
  return out;
}

}  // namespace evar::sim
