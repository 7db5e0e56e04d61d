#include "truth_checks.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>

#include "evar/geometry/closest_point.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/ray_caster.hpp"
#include "evar/sim/tube_mesh.hpp"

namespace evar::sim::detail {

VesselRoles vessel_roles(const ExampleScene& scene, const std::string& who) {
  if (scene.device.size() < 2) throw std::invalid_argument(who + ": the device needs >= 2 points");
  VesselRoles r;
  bool have_aorta = false;
  for (std::size_t vi = 0; vi < scene.vessels.size(); ++vi) {
    const auto& v = scene.vessels[vi];
    if (v.centerline.size() < 3 || v.radii_mm.size() != v.centerline.size())
      throw std::invalid_argument(who + ": vessel " + v.name + " needs >= 3 centerline points and radii");
    if (v.kind == geometry::VesselKind::Aorta) r.aorta = vi, have_aorta = true;
    else r.iliacs.push_back(vi);
  }
  if (!have_aorta || r.iliacs.empty()) throw std::invalid_argument(who + ": need an aorta and an iliac");
  const Eigen::Vector3d access = scene.device.back();
  r.carrier = *std::min_element(r.iliacs.begin(), r.iliacs.end(), [&](std::size_t a, std::size_t b) {
    return (scene.vessels[a].centerline.back() - access).norm() < (scene.vessels[b].centerline.back() - access).norm();
  });
  const ExampleVessel& aorta = scene.vessels[r.aorta];
  const auto aorta_arc = geometry::arc_lengths(aorta.centerline);
  r.overlap.assign(scene.vessels.size(), 0);
  r.hub_arc_mm = aorta_arc.back();
  for (const std::size_t vi : r.iliacs) {
    double start_arc = 0.0;
    r.overlap[vi] = overlap_length(scene.vessels[vi], aorta, aorta_arc, &start_arc);
    r.hub_arc_mm = std::min(r.hub_arc_mm, start_arc);
  }
  return r;
}

std::size_t overlap_length(const ExampleVessel& iliac, const ExampleVessel& aorta, const std::vector<double>& aorta_arc,
                           double* start_arc_on_aorta) {
  const geometry::PolylineProjector projector(aorta.centerline);
  std::size_t n = 0;
  for (; n < iliac.centerline.size(); ++n) {
    const auto proj = projector.project(iliac.centerline[n]);
    if (n == 0) *start_arc_on_aorta = proj.arc_length_mm;
    if (n > 0 && (proj.beyond_end || proj.distance_mm > interpolate_along(aorta_arc, aorta.radii_mm, proj.arc_length_mm)))
      break;
  }
  return std::max<std::size_t>(n, 1);
}

std::optional<Eigen::Vector3d> device_crossing(const geometry::Polyline& device, const Eigen::Vector3d& centre,
                                               const Eigen::Vector3d& normal, double reach) {
  std::optional<Eigen::Vector3d> best;
  double best_d2 = reach * reach;
  double s0 = (device[0] - centre).dot(normal);
  for (std::size_t k = 0; k + 1 < device.size(); ++k) {
    const double s1 = (device[k + 1] - centre).dot(normal);
    if ((s0 <= 0.0) != (s1 <= 0.0)) {
      const Eigen::Vector3d x = device[k] + (s0 / (s0 - s1)) * (device[k + 1] - device[k]);
      const double d2 = (x - centre).squaredNorm();
      if (d2 < best_d2) {
        best_d2 = d2;
        best = x;
      }
    }
    s0 = s1;
  }
  return best;
}

std::size_t wall_vessel(const std::vector<ExampleVessel>& vessels, const Eigen::Vector3d& x) {
  std::size_t best = 0;
  double best_gap = std::numeric_limits<double>::infinity();
  for (std::size_t vi = 0; vi < vessels.size(); ++vi) {
    const auto& v = vessels[vi];
    const auto proj = geometry::project_onto(v.centerline, x);
    const double gap = std::abs(proj.distance_mm - interpolate_along(geometry::arc_lengths(v.centerline), v.radii_mm, proj.arc_length_mm));
    if (gap < best_gap) {
      best_gap = gap;
      best = vi;
    }
  }
  return best;
}

std::vector<DeviceOutside> device_outside(const std::vector<Eigen::Vector3d>& device,
                                          const std::vector<VesselDistortion>& vessels, double slack_mm) {
  std::vector<geometry::RayCaster> casters;
  for (const auto& v : vessels) casters.emplace_back(v.mesh, geometry::RayCaster::BuildQuality::Low);
  std::vector<DeviceOutside> out;
  for (std::size_t k = 0; k < device.size(); ++k) {
    bool inside = false;
    for (const auto& c : casters) inside = inside || c.contains(device[k]);
    if (inside) continue;
    DeviceOutside o;
    o.point = k;
    o.gap_mm = std::numeric_limits<double>::infinity();
    for (std::size_t vi = 0; vi < vessels.size(); ++vi) {
      const auto sp = geometry::closest_point_on_mesh(vessels[vi].mesh, device[k]);
      if (sp.distance_mm < o.gap_mm) {
        o.gap_mm = sp.distance_mm;
        o.vessel = vi;
        o.wall_point = sp.point;
      }
    }
    if (o.gap_mm > slack_mm) out.push_back(o);
  }
  return out;
}

void record_outside(const std::vector<DeviceOutside>& outside, DeviceDistortion& out) {
  out.device_points_outside = static_cast<int>(outside.size());
  out.worst_outside_mm = 0.0;
  out.worst_outside_point = 0;
  for (const auto& o : outside)
    if (o.gap_mm > out.worst_outside_mm) {
      out.worst_outside_mm = o.gap_mm;
      out.worst_outside_point = o.point;
      out.worst_outside_vessel = out.vessels.at(o.vessel).name;
    }
}

}  // namespace evar::sim::detail
