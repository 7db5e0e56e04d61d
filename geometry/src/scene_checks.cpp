#include "scene_checks.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "evar/base/input_error.hpp"
#include "evar/base/quantity_text.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/ray_caster.hpp"

namespace evar::geometry::detail {
namespace {

// At most this many vertices of a mesh are tried against another.
constexpr Eigen::Index kSampled = 400;
// This share of a vessel's vertices inside or on another's surface: it is within it.
constexpr double kNestedShare = 0.8;
// On a surface: closer than this (mm), whatever rounding a copy went through.
constexpr double kOnSurfaceMm = 0.01;

[[noreturn]] void refuse(const Scene& scene, const std::string& why) {
  throw base::InputError(scene.file.string() + ": " + why);
}

// How far the mesh reaches past its centerline's ends, along the centerline's end
// directions (mm, 0 when it does not), and its median distance from the centerline.
struct Reach {
  double past_start_mm = 0.0, past_end_mm = 0.0, median_radius_mm = 0.0;
};

Reach reach_of(const Vessel& v) {
  Reach r;
  const auto& c = v.centerline;
  const Eigen::Vector3d t0 = (c[1] - c[0]).normalized();
  const Eigen::Vector3d t1 = (c[c.size() - 1] - c[c.size() - 2]).normalized();
  const PolylineProjector onto(c);
  std::vector<double> distance;
  int segment = -1;
  const auto& V = v.mesh.mesh.V;
  distance.reserve(static_cast<std::size_t>(V.rows()));
  for (Eigen::Index k = 0; k < V.rows(); ++k) {
    const Eigen::Vector3d p = V.row(k).transpose();
    const auto at = onto.project(p, segment, &segment);
    distance.push_back(at.distance_mm);
    if (at.beyond_start) r.past_start_mm = std::max(r.past_start_mm, (c.front() - p).dot(t0));
    if (at.beyond_end) r.past_end_mm = std::max(r.past_end_mm, (p - c.back()).dot(t1));
  }
  if (!distance.empty()) {
    auto mid = distance.begin() + static_cast<std::ptrdiff_t>(distance.size() / 2);
    std::nth_element(distance.begin(), mid, distance.end());
    r.median_radius_mm = *mid;
  }
  return r;
}

}  // namespace

void check_vessels_apart(const Scene& scene) {
  const auto& vessels = scene.vessels;
  // The same surface twice (one segmentation given for several vessels).
  for (std::size_t i = 0; i < vessels.size(); ++i)
    for (std::size_t j = i + 1; j < vessels.size(); ++j) {
      const auto& a = vessels[i].mesh.mesh;
      const auto& b = vessels[j].mesh.mesh;
      if (a.V.rows() == b.V.rows() && a.F.rows() == b.F.rows() && a.V == b.V && a.F == b.F)
        refuse(scene, "vessels '" + vessels[i].name + "' and '" + vessels[j].name + "' have the same mesh (" +
                          vessels[i].mesh_path.filename().string() + ", " + vessels[j].mesh_path.filename().string() +
                          "): each vessel needs its own piece of the surface; cut one surface into vessels with "
                          "`evarnode scene`");
    }
  // One inside or on another.
  for (std::size_t j = 0; j < vessels.size(); ++j) {
    const auto& outer = vessels[j].mesh.mesh;
    const RayCaster caster(outer, RayCaster::BuildQuality::Low);
    const bool closed = is_closed(outer);
    for (std::size_t i = 0; i < vessels.size(); ++i) {
      if (i == j) continue;
      const auto& V = vessels[i].mesh.mesh.V;
      const Eigen::Index step = std::max<Eigen::Index>(1, V.rows() / kSampled);
      Eigen::Index tried = 0, within = 0;
      for (Eigen::Index k = 0; k < V.rows(); k += step, ++tried) {
        const Eigen::Vector3d p = V.row(k).transpose();
        const auto q = caster.closest_point(p, kOnSurfaceMm);
        within += (q || (closed && caster.contains(p))) ? 1 : 0;
      }
      if (tried > 0 && static_cast<double>(within) >= kNestedShare * static_cast<double>(tried))
        refuse(scene, "the mesh of vessel '" + vessels[i].name + "' (" + vessels[i].mesh_path.filename().string() +
                          ") lies " + (closed ? "inside or on" : "on") + " that of '" + vessels[j].name + "' (" +
                          vessels[j].mesh_path.filename().string() + ") for " +
                          std::to_string(static_cast<int>(std::lround(100.0 * static_cast<double>(within) /
                                                                      static_cast<double>(tried)))) +
                          "% of its vertices: two vessels must be two pieces of the surface, not one inside the "
                          "other; cut one surface into vessels with `evarnode scene`");
    }
  }
  // Reaching far past its centerline: a branching tree given as one vessel, or a
  // centerline that stops short.
  for (const auto& v : vessels) {
    const Reach r = reach_of(v);
    const double allowed = 10.0 + 1.5 * r.median_radius_mm;
    const double past = std::max(r.past_start_mm, r.past_end_mm);
    if (past > allowed)
      refuse(scene, "the mesh of vessel '" + v.name + "' (" + v.mesh_path.filename().string() + ") reaches " +
                        base::quantity_text(past, "mm", 1) + " past the " +
                        (r.past_end_mm >= r.past_start_mm ? "distal" : "proximal") + " end of its centerline (" +
                        v.centerline_path.filename().string() + "; at most " + base::quantity_text(allowed, "mm", 1) +
                        " for a lumen of radius " + base::quantity_text(r.median_radius_mm, "mm", 1) +
                        "): a mesh of a branching tree given as one vessel, or a centerline that stops short; cut the "
                        "surface into vessels and trim their centerlines with `evarnode scene`");
  }
}

}  // namespace evar::geometry::detail
