#include "evar/sim/conforming_distortion.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "evar/geometry/polyline.hpp"
#include "evar/sim/tube_mesh.hpp"
#include "seeded_uniform.hpp"
#include "section_sweep.hpp"
#include "truth_checks.hpp"

namespace evar::sim {
namespace {

using geometry::Polyline;

double smoothstep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

// A curve by arc length, continued straight past both ends.
class ArcCurve {
 public:
  explicit ArcCurve(Polyline p) : p_(std::move(p)), arc_(geometry::arc_lengths(p_)) {}
  double length() const { return arc_.back(); }
  const Polyline& points() const { return p_; }
  Eigen::Vector3d at(double s) const {
    if (s < 0.0) return p_.front() + s * (p_[1] - p_[0]).normalized();
    if (s > length()) return p_.back() + (s - length()) * (p_.back() - p_[p_.size() - 2]).normalized();
    return geometry::point_at(p_, arc_, s);
  }
  Eigen::Vector3d tangent(double s) const { return geometry::tangent_at(p_, arc_, std::clamp(s, 0.0, length())); }

 private:
  Polyline p_;
  std::vector<double> arc_;
};

// The infrarenal aorta as a string under tension on a soft bed, held at zero up to
// `held` (the renal level): per coordinate, u minimizes
//   T Σ |u_{i+1} - u_i|² + Σ |u_i|² + W Σ_contacts |u_i - g_i|²
// (a tridiagonal system, solved by the Thomas algorithm).
Eigen::MatrixX3d solve_string(std::size_t n, std::size_t held, double tension, const std::vector<char>& active,
                              const std::vector<Eigen::Vector3d>& target) {
  const double w = 1e4 * (1.0 + tension);
  Eigen::MatrixX3d u = Eigen::MatrixX3d::Zero(static_cast<Eigen::Index>(n), 3);
  if (held + 1 >= n) return u;
  const std::size_t m = n - held - 1;  // unknowns: points held+1 .. n-1
  std::vector<double> diag(m), upper(m, -tension);
  Eigen::MatrixX3d rhs = Eigen::MatrixX3d::Zero(static_cast<Eigen::Index>(m), 3);
  for (std::size_t k = 0; k < m; ++k) {
    const std::size_t i = held + 1 + k;
    diag[k] = 1.0 + tension * (i + 1 < n ? 2.0 : 1.0);  // the held neighbour above counts, at zero
    if (active[i]) {
      diag[k] += w;
      rhs.row(static_cast<Eigen::Index>(k)) = w * target[i].transpose();
    }
  }
  // Forward sweep, back substitution.
  std::vector<double> c(m);
  c[0] = upper[0] / diag[0];
  rhs.row(0) /= diag[0];
  for (std::size_t k = 1; k < m; ++k) {
    const double denom = diag[k] + tension * c[k - 1];
    c[k] = upper[k] / denom;
    rhs.row(static_cast<Eigen::Index>(k)) = (rhs.row(static_cast<Eigen::Index>(k)) + tension * rhs.row(static_cast<Eigen::Index>(k - 1))) / denom;
  }
  for (std::size_t k = m - 1; k-- > 0;)
    rhs.row(static_cast<Eigen::Index>(k)) -= c[k] * rhs.row(static_cast<Eigen::Index>(k + 1));
  u.bottomRows(static_cast<Eigen::Index>(m)) = rhs;
  return u;
}

}  // namespace

ConformingOptions draw_conforming_options(std::uint64_t seed) {
  SeededUniform draw(seed ^ 0xc0f0'2a11'0b5e'0001ULL);
  ConformingOptions o;
  o.wire_offset_fraction = draw(0.0, 0.5);
  o.fold_fraction = draw(0.0, 1.0);
  o.aorta_decay_mm = draw(15.0, 40.0);
  return o;
}

geometry::TriangleMesh resweep_turning(const geometry::TriangleMesh& mesh, const Polyline& centerline, const Polyline& moved,
                                       bool turn) {
  return detail::SectionSweep(centerline, moved, std::vector<double>(centerline.size(), turn ? 1.0 : 0.0)).map(mesh);
}

DeviceDistortion distort_by_conforming(const ExampleScene& scene, const ConformingOptions& o) {
  if (!(o.wire_offset_fraction >= 0.0 && o.wire_offset_fraction <= 1.0 && o.fold_fraction >= 0.0 && o.fold_fraction <= 1.0 &&
        o.aorta_decay_mm > 0.0 && o.junction_blend_mm > 0.0 && o.clearance_mm >= 0.0))
    throw std::invalid_argument("distort_by_conforming: fractions must lie in [0, 1], lengths be positive");
  const detail::VesselRoles roles = detail::vessel_roles(scene, "distort_by_conforming");
  const std::size_t ai = roles.aorta, ci = roles.carrier;
  const std::vector<std::size_t>& overlap = roles.overlap;
  const double hub_arc = roles.hub_arc_mm;
  const ExampleVessel& aorta = scene.vessels[ai];
  const auto aorta_arc = geometry::arc_lengths(aorta.centerline);

  // The aorta is held at the renal level (the mean height of the renal landmarks on it, or
  // a quarter of its length without them).
  double held_arc = 0.25 * aorta_arc.back();
  {
    double sum = 0.0;
    int count = 0;
    for (const auto& lm : scene.landmarks)
      if (detail::wall_vessel(scene.vessels, lm.position_lps) == ai && lm.label.find("renal") != std::string::npos) {
        sum += geometry::project_onto(aorta.centerline, lm.position_lps).arc_length_mm;
        ++count;
      }
    if (count > 0) held_arc = sum / count;
  }
  if (!(hub_arc > held_arc + 10.0)) throw std::invalid_argument("distort_by_conforming: the iliacs start at or above the renal level");
  const std::size_t held = static_cast<std::size_t>(std::upper_bound(aorta_arc.begin(), aorta_arc.end(), held_arc) - aorta_arc.begin()) - 1;

  const ExampleVessel& carrier = scene.vessels[ci];
  const auto carrier_arc = geometry::arc_lengths(carrier.centerline);
  const auto in_carrier = [&](const Eigen::Vector3d& x) {
    const auto proj = geometry::project_onto(carrier.centerline, x);
    return !proj.beyond_start && !proj.beyond_end &&
           proj.distance_mm <= interpolate_along(carrier_arc, carrier.radii_mm, proj.arc_length_mm) - 0.5 * scene.device_thickness_mm;
  };

  // The aneurysm sac is a bag, not a tube: its sections translate (a section 30 mm or more
  // across, turned with its centerline, would sweep through its neighbours), and contact is
  // found in the preoperative section planes.
  const auto aorta_tangent = detail::point_tangents(aorta.centerline);
  // Aortic contact: sections below the renal level that the wire crosses outside the lumen
  // (less the wire's half thickness and the clearance) get a target just past it; the
  // string is solved again until none is intruded.
  const double wall = 0.5 * scene.device_thickness_mm + o.clearance_mm;
  const std::size_t na = aorta.centerline.size();
  std::vector<char> active(na, 0);
  std::vector<Eigen::Vector3d> target(na, Eigen::Vector3d::Zero());
  Eigen::MatrixX3d ua = Eigen::MatrixX3d::Zero(static_cast<Eigen::Index>(na), 3);
  DeviceDistortion out;
  out.carrier = scene.vessels[ci].name;
  double intrusion = 0.0;
  for (int round = 0;; ++round) {
    Polyline now = aorta.centerline;
    for (std::size_t i = 0; i < na; ++i) now[i] += ua.row(static_cast<Eigen::Index>(i)).transpose();
    intrusion = 0.0;
    bool changed = false;
    for (std::size_t i = 1; i + 1 < na; ++i) {
      const auto x = detail::device_crossing(scene.device, now[i], aorta_tangent[i], aorta.radii_mm[i] + 15.0);
      if (!x) continue;
      const Eigen::Vector3d e = *x - now[i];
      const double over = e.norm() - (aorta.radii_mm[i] - wall);
      // In the bifurcation the carrier iliac holds the wire where the aorta does not.
      if (over <= 0.0 || (aorta_arc[i] >= hub_arc && in_carrier(*x))) continue;
      intrusion = std::max(intrusion, over);
      if (over <= 0.005 || i <= held) continue;  // held sections cannot give way
      const Eigen::Vector3d from = active[i] ? target[i] : Eigen::Vector3d(ua.row(static_cast<Eigen::Index>(i)).transpose());
      target[i] = from + (over + 0.02) * e.normalized();
      active[i] = 1;
      changed = true;
    }
    if (!changed) break;
    out.rounds += 1;
    if (round == o.max_contact_rounds)
      throw std::runtime_error("distort_by_conforming: aortic contact did not settle in " + std::to_string(round) + " rounds");
    ua = solve_string(na, held, o.aorta_decay_mm * o.aorta_decay_mm, active, target);
  }
  out.max_intrusion_mm = intrusion;

  // An iliac's overlap moves with the aorta around it.
  const geometry::PolylineProjector aorta_projector(aorta.centerline);
  const auto aorta_shift = [&](const Eigen::Vector3d& x) {
    int seg = 0;
    const auto proj = aorta_projector.project(x, -1, &seg);
    const auto j = static_cast<std::size_t>(seg);
    const double len = aorta_arc[j + 1] - aorta_arc[j];
    const double f = len > 0.0 ? std::clamp((proj.arc_length_mm - aorta_arc[j]) / len, 0.0, 1.0) : 0.0;
    return Eigen::Vector3d((1.0 - f) * ua.row(static_cast<Eigen::Index>(j)).transpose() +
                           f * ua.row(static_cast<Eigen::Index>(j + 1)).transpose());
  };

  Polyline aorta_now = aorta.centerline;
  for (std::size_t i = 0; i < na; ++i) aorta_now[i] += ua.row(static_cast<Eigen::Index>(i)).transpose();
  const auto in_moved_aorta = [&](const Eigen::Vector3d& x) {
    const auto proj = geometry::project_onto(aorta_now, x);
    return !proj.beyond_start && !proj.beyond_end &&
           proj.distance_mm <= interpolate_along(aorta_arc, aorta.radii_mm, proj.arc_length_mm) - wall;
  };

  std::vector<Polyline> moved(scene.vessels.size());
  // How much each section turns with its centerline: the aorta's not at all (a sac is a
  // bag), an iliac's fully, except where it leaves the bifurcation, whose sections move
  // with the aorta and take the turn onto the wire over the blend length.
  std::vector<std::vector<double>> turn(scene.vessels.size());
  for (std::size_t vi = 0; vi < scene.vessels.size(); ++vi) {
    const ExampleVessel& v = scene.vessels[vi];
    Polyline& c = moved[vi];
    c = v.centerline;
    turn[vi].assign(c.size(), vi == ai ? 0.0 : 1.0);
    if (vi == ai) {
      for (std::size_t i = 0; i < na; ++i) c[i] += ua.row(static_cast<Eigen::Index>(i)).transpose();
      continue;
    }
    const std::size_t j0 = overlap[vi];
    if (j0 + 2 >= c.size()) throw std::invalid_argument("distort_by_conforming: iliac " + v.name + " lies inside the aorta");
    for (std::size_t i = 0; i < j0; ++i) c[i] += aorta_shift(v.centerline[i]);
    const Eigen::Vector3d junction = aorta_shift(v.centerline[j0 - 1]);
    const auto arc = geometry::arc_lengths(v.centerline);
    const double free_length = arc.back() - arc[j0];
    for (std::size_t i = 0; i < c.size(); ++i) turn[vi][i] = i < j0 ? 0.0 : smoothstep((arc[i] - arc[j0]) / o.junction_blend_mm);
    if (vi != ci) {
      // The other iliac follows the bifurcation, fading to its groin.
      for (std::size_t i = j0; i < c.size(); ++i) c[i] += (1.0 - (arc[i] - arc[j0]) / free_length) * junction;
      continue;
    }
    // The carrier threaded on the wire (from the access up: arc 0 at the access, the wire
    // continued straight past it), its arc mapped onto the wire's: folded where the wire's
    // course is shorter, the rest slid distally.
    Polyline up(scene.device.rbegin(), scene.device.rend());
    const ArcCurve wire(up);
    const geometry::PolylineProjector on_wire(wire.points());
    const double top = on_wire.project(v.centerline[j0]).arc_length_mm;
    const double bottom = on_wire.project(v.centerline.back()).arc_length_mm;
    if (!(top - bottom > 1.0))
      throw std::invalid_argument("distort_by_conforming: the device does not run down the " + v.name +
                                  " (its course there is " + std::to_string(top - bottom) + " mm long)");
    const double ratio = (top - bottom) / free_length;
    const double scale = ratio >= 1.0 ? ratio : 1.0 - o.fold_fraction * (1.0 - ratio);
    std::vector<Eigen::Vector3d> offset(c.size(), Eigen::Vector3d::Zero());
    std::vector<double> along(c.size(), 0.0);
    for (std::size_t i = j0; i < c.size(); ++i) {
      along[i] = top - (arc[i] - arc[j0]) * scale;
      const auto proj = on_wire.project(v.centerline[i]);
      const Eigen::Vector3d e = v.centerline[i] - proj.point;
      const Eigen::Vector3d t = wire.tangent(along[i]);
      offset[i] = o.wire_offset_fraction * (e - e.dot(t) * t);
    }
    // The offsets smoothed along the vessel (their wire projections jump across loops),
    // then kept inside the lumen with the wire's half thickness and the clearance.
    constexpr std::size_t kHalfWindow = 8;
    std::vector<Eigen::Vector3d> smooth(c.size(), Eigen::Vector3d::Zero());
    for (std::size_t i = j0; i < c.size(); ++i) {
      const std::size_t lo = std::max(j0, i >= kHalfWindow ? i - kHalfWindow : 0), hi = std::min(c.size() - 1, i + kHalfWindow);
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (std::size_t k = lo; k <= hi; ++k) sum += offset[k];
      const Eigen::Vector3d t = wire.tangent(along[i]);
      Eigen::Vector3d s = sum / static_cast<double>(hi - lo + 1);
      s -= s.dot(t) * t;
      const double room = std::max(0.0, v.radii_mm[i] - wall - 0.2);
      if (s.norm() > room) s *= room / s.norm();
      smooth[i] = s;
    }
    // From the bifurcation the vessel turns onto the wire: its offset from the wire goes
    // from the junction's own (moved with the aorta) to the threaded one over the blend
    // length, along the wire, so the course advances along the wire as smoothly as the
    // wire does (its sections take the turn over the same length, see `turn`).
    const Eigen::Vector3d junction_offset = v.centerline[j0] + junction - wire.at(along[j0]);
    for (std::size_t i = j0; i < c.size(); ++i) {
      const double w = smoothstep((arc[i] - arc[j0]) / o.junction_blend_mm);
      c[i] = wire.at(along[i]) + (1.0 - w) * junction_offset + w * smooth[i];
    }
    // Where the turn from the bifurcation onto the wire leaves the wire outside a section
    // (a stiff wire cuts the corner), the wall gives way there by contact, unless the aorta
    // holds the wire there.
    // Each push spreads over two radii either side (a wall does not kink at one section),
    // weights normalized so that neighbours pushed alike move alike; repeated until no
    // section is intruded.
    for (int pass = 0; pass < o.max_contact_rounds; ++pass) {
      const auto tangent = detail::point_tangents(c);
      std::vector<Eigen::Vector3d> push(c.size(), Eigen::Vector3d::Zero());
      std::vector<char> pushed(c.size(), 0);
      bool any = false;
      for (std::size_t i = 1; i + 1 < c.size(); ++i) {
        const auto x = detail::device_crossing(scene.device, c[i], tangent[i], v.radii_mm[i] + 15.0);
        if (!x) continue;
        const Eigen::Vector3d e = *x - c[i];
        const double over = e.norm() - (v.radii_mm[i] - wall);
        if (over <= 0.005 || in_moved_aorta(*x)) continue;
        push[i] = (over + 0.02) * e.normalized();
        pushed[i] = 1;
        any = true;
      }
      if (!any) break;
      if (pass + 1 == o.max_contact_rounds)
        throw std::runtime_error("distort_by_conforming: contact in the " + v.name + " did not settle");
      Polyline next = c;
      for (std::size_t k = 0; k < c.size(); ++k) {
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        double weight = 0.0;
        for (std::size_t i = 1; i + 1 < c.size(); ++i) {
          if (!pushed[i]) continue;
          const double w = 1.0 - std::abs(arc[k] - arc[i]) / (2.0 * v.radii_mm[i]);
          if (w <= 0.0) continue;
          sum += w * push[i];
          weight += w;
        }
        if (weight > 0.0) next[k] += sum / std::max(1.0, weight);
      }
      c = std::move(next);
    }
  }

  for (std::size_t vi = 0; vi < scene.vessels.size(); ++vi) {
    const ExampleVessel& v = scene.vessels[vi];
    VesselDistortion vd;
    vd.name = v.name;
    vd.centerline = moved[vi];
    for (std::size_t i = 0; i < v.centerline.size(); ++i)
      vd.max_displacement_mm = std::max(vd.max_displacement_mm, (vd.centerline[i] - v.centerline[i]).norm());
    vd.contact_sections = vi == ai ? static_cast<int>(std::count(active.begin(), active.end(), 1))
                          : vi == ci ? static_cast<int>(v.centerline.size() - overlap[vi])
                                     : 0;
    vd.mesh = detail::SectionSweep(v.centerline, vd.centerline, turn[vi]).map(v.mesh);
    out.vessels.push_back(std::move(vd));
  }
  detail::record_outside(detail::device_outside(scene.device, out.vessels, scene.device_thickness_mm), out);

  for (const auto& lm : scene.landmarks) {
    const std::size_t vi = detail::wall_vessel(scene.vessels, lm.position_lps);
    const detail::SectionSweep sweep(scene.vessels[vi].centerline, out.vessels[vi].centerline, turn[vi]);
    int hint = -1;
    out.landmarks.push_back({lm.label, sweep.map(lm.position_lps, &hint)});
  }
  return out;
}

}  // namespace evar::sim
