#include "evar/deform/control_points.hpp"

#include "ordered_pairing.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace evar::deform {
namespace {

struct Candidate {
  Handle handle;
  double penetration_mm;  // |d − h|
};

// Casts the ray from centerline point c toward device point d; a wall hit before d means
// the device is outside there.
void try_ray(const geometry::RayCaster& caster, const Eigen::Vector3d& c, const Eigen::Vector3d& d, double arc,
             double thickness, std::vector<Candidate>& out) {
  const Eigen::Vector3d cd = d - c;
  const double reach = cd.norm();
  if (!(reach > 1e-9)) return;
  // t_min skips a wall the ray starts on (a centerline ending on a cap).
  const auto hit = caster.first_hit(c, cd, reach, 1e-6);
  if (!hit) return;
  const Eigen::Vector3d dh = d - hit->point;
  const double pen = dh.norm();
  if (!(pen > 1e-9)) return;
  // Eq. 6, s = d − h + Δd (d − h)/|d − h|: h lies on the ray from c to d, so (d − h)/|d − h|
  // is the ray's direction, taken from the ray itself (d − h alone is rounding where d
  // is within a hair of the wall).
  const Eigen::Vector3d s = dh + thickness * cd / reach;
  out.push_back({{hit->point, hit->face, hit->barycentric, d, s, arc}, pen});
}

}  // namespace

std::vector<Eigen::Vector3d> device_points_in_vessel(const geometry::Polyline& centerline, const RadiusProfile& radius,
                                                     const geometry::Polyline& device, const ControlPointOptions& options) {
  std::vector<Eigen::Vector3d> inside;
  const geometry::PolylineProjector onto_centerline(centerline);
  int segment = -1;
  // Samples placed symmetrically: the device given from either end gives the same ones.
  for (const auto& d : geometry::resample_symmetric(device, options.sample_step_mm)) {
    const auto foot = onto_centerline.project(d, segment, &segment);
    if (foot.beyond_start || foot.beyond_end) continue;
    if (foot.distance_mm > options.reach_radii * radius.at(foot.arc_length_mm)) continue;
    inside.push_back(d);
  }
  return inside;
}

std::vector<Handle> select_control_points(const geometry::TriangleMesh& mesh, const geometry::RayCaster& caster,
                                          const geometry::Polyline& centerline, const RadiusProfile& radius,
                                          const geometry::Polyline& device, const ControlPointOptions& options,
                                          const LumenTest& in_other_lumen,
                                          const std::optional<Eigen::Vector3d>& device_entry) {
  if (!(options.sample_step_mm > 0.0) || !(options.device_thickness_mm >= 0.0))
    throw std::invalid_argument("control points: sample step must be > 0 and device thickness >= 0");
  const double spacing = options.spacing_mm > 0.0 ? options.spacing_mm : 1.5 * geometry::median_edge_length(mesh);
  // An iliac entered at its junction is paired along the device's run from there on; a
  // device that does not pass the junction (or no entry given) by the device points
  // within reach.
  geometry::Polyline ours;
  std::vector<SectionPartner> pairs;
  if (options.pair_in_order && device_entry) {
    ours = device_run_from(centerline, device, *device_entry, options.sample_step_mm);
    if (!ours.empty()) pairs = ordered_pairing_from_entry(centerline, ours, options.sample_step_mm);
  }
  if (pairs.empty()) {
    ours = device_points_in_vessel(centerline, radius, device, options);
    if (options.pair_in_order) pairs = ordered_pairing(centerline, ours, options.sample_step_mm);
  }
  std::vector<Candidate> candidates;
  const geometry::PolylineProjector onto_centerline(centerline);
  int segment = -1;
  const auto elsewhere = [&](const Eigen::Vector3d& d) { return in_other_lumen && in_other_lumen(d); };
  if (!pairs.empty()) {
    // Every section toward its partner, and every device sample from the section whose
    // partner it is.
    const auto centerline_arc = geometry::arc_lengths(centerline);
    const auto device_arc = geometry::arc_lengths(ours);
    for (const auto& p : pairs) {
      const Eigen::Vector3d d = geometry::point_at(ours, device_arc, p.device_arc_mm);
      if (elsewhere(d)) continue;
      try_ray(caster, geometry::point_at(centerline, centerline_arc, p.section_arc_mm), d, p.section_arc_mm,
              options.device_thickness_mm, candidates);
    }
    for (std::size_t i = 0; i < ours.size(); ++i) {
      if (elsewhere(ours[i])) continue;
      const double s = section_arc_of(pairs, device_arc[i]);
      try_ray(caster, geometry::point_at(centerline, centerline_arc, s), ours[i], s, options.device_thickness_mm,
              candidates);
    }
    // A ray toward a partner far along the vessel can leave through an end cap, and one to
    // a device point level with an end runs in the cap's plane, hitting its rim or not by
    // rounding; the caps close the model where the segmentation stopped, they are no wall
    // to push. So no handle within a sample step of either end.
    const double vessel_end = centerline_arc.back();
    std::erase_if(candidates, [&](const Candidate& c) {
      const double s = onto_centerline.project(c.handle.hit).arc_length_mm;
      return s < options.sample_step_mm || s > vessel_end - options.sample_step_mm;
    });
  } else if (ours.size() >= 1) {
    // Device samples -> their foot on the centerline.
    for (const auto& d : ours) {
      if (elsewhere(d)) continue;
      const auto foot = onto_centerline.project(d, segment, &segment);
      try_ray(caster, foot.point, d, foot.arc_length_mm, options.device_thickness_mm, candidates);
    }
    // Centerline samples -> nearest point of this vessel's part of the device (the
    // paper's direction: it covers stretches where the device runs beside the vessel).
    if (ours.size() >= 2) {
      const auto arc = geometry::arc_lengths(centerline);
      const geometry::PolylineProjector onto_device(ours);
      int device_segment = -1;
      for (double s = 0.0; s <= arc.back(); s += options.sample_step_mm) {
        const Eigen::Vector3d c = geometry::point_at(centerline, arc, s);
        const auto near = onto_device.project(c, device_segment, &device_segment);
        const double r = radius.at(s);
        if (near.distance_mm > options.reach_radii * r) continue;
        // Only rays across the lumen: a device point far along the axis is reached
        // through an end cap, which says nothing about the wall.
        if (std::abs(onto_centerline.project(near.point, segment, &segment).arc_length_mm - s) > r) continue;
        if (elsewhere(near.point)) continue;
        try_ray(caster, c, near.point, s, options.device_thickness_mm, candidates);
      }
    }
  }
  // Resampling: deepest first, then keep a candidate only if no kept handle is closer
  // than `spacing` (hit points), so handles are even however the vessel winds. Equal
  // depths are ordered by where they hit, not by the order the device was given in.
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    if (a.penetration_mm != b.penetration_mm) return a.penetration_mm > b.penetration_mm;
    return std::lexicographical_compare(a.handle.hit.data(), a.handle.hit.data() + 3, b.handle.hit.data(),
                                        b.handle.hit.data() + 3);
  });
  std::vector<Handle> kept;
  for (const auto& c : candidates) {
    const bool crowded = std::any_of(kept.begin(), kept.end(), [&](const Handle& h) {
      return (h.hit - c.handle.hit).norm() < spacing;
    });
    if (!crowded) kept.push_back(c.handle);
  }
  std::sort(kept.begin(), kept.end(), [](const Handle& a, const Handle& b) { return a.arc_mm < b.arc_mm; });
  return kept;
}

std::map<int, Eigen::Vector3d> handle_vertex_targets(const geometry::TriangleMesh& mesh, const std::vector<Handle>& handles) {
  std::map<int, std::pair<Eigen::Vector3d, double>> acc;  // Σ β s, Σ β
  for (const auto& h : handles)
    for (int j = 0; j < 3; ++j) {
      const int v = mesh.F(h.face, j);
      // Even a corner with β = 0 moves with the triangle; weight it a little.
      const double beta = std::max(h.barycentric[j], 0.0) + 1e-3;
      auto& [sum, wsum] = acc.try_emplace(v, Eigen::Vector3d::Zero(), 0.0).first->second;
      sum += beta * h.shift;
      wsum += beta;
    }
  std::map<int, Eigen::Vector3d> targets;
  for (const auto& [v, sw] : acc) targets[v] = mesh.V.row(v).transpose() + sw.first / sw.second;
  return targets;
}

}  // namespace evar::deform
