#include "evar/deform/device_containment.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <stdexcept>

#include "evar/geometry/surface_side.hpp"

namespace evar::deform {

DeviceContainment measure_device_containment(const std::vector<NamedSurface>& vessels, const geometry::Polyline& device,
                                             double sample_step_mm) {
  if (!(sample_step_mm > 0.0)) throw std::invalid_argument("device containment: the sample step must be > 0");
  DeviceContainment out;
  if (device.size() < 2) return out;
  // Each vessel's surface is built when a sample first asks it (a vessel the device never
  // comes near, the other iliac, costs nothing).
  std::vector<std::optional<geometry::SurfaceSide>> sides(vessels.size());
  const auto side = [&](std::size_t i) -> const geometry::SurfaceSide& {
    if (!sides[i]) sides[i].emplace(*vessels[i].mesh, vessels[i].cap_faces);
    return *sides[i];
  };
  std::vector<std::optional<geometry::PolylineProjector>> extents(vessels.size());
  for (std::size_t i = 0; i < vessels.size(); ++i)
    if (vessels[i].centerline && vessels[i].centerline->size() >= 2) extents[i].emplace(*vessels[i].centerline);
  const auto within_extent = [&extents](std::size_t i, const Eigen::Vector3d& p) {
    if (!extents[i]) return true;
    const auto at = extents[i]->project(p);
    return !at.beyond_start && !at.beyond_end;
  };

  const geometry::Polyline samples = geometry::resample(device, sample_step_mm);
  enum class State { Inside, Outside, Unjudged };
  struct Sample {
    State state = State::Unjudged;
    double depth_mm = 0.0;
    std::size_t nearest = 0;
    double arc_mm = 0.0;
  };
  std::vector<Sample> s(samples.size());
  // Per vessel, the last distance found to it and where: the next sample's is within
  // that plus the step, which bounds its search. The vessel a sample was inside is asked
  // first for the next one.
  std::vector<double> last_distance(vessels.size(), std::numeric_limits<double>::infinity());
  std::vector<Eigen::Vector3d> last_point(vessels.size(), Eigen::Vector3d::Zero());
  std::vector<std::size_t> order(vessels.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  // The last sample found inside a vessel and a ball round it that holds none of that
  // vessel's wall and reaches none of its openings: a sample within it is inside too, without
  // asking (SurfaceSide::inside_ball_radius_mm).
  Eigen::Vector3d ball_centre = Eigen::Vector3d::Zero();
  double ball_radius = 0.0;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    if (k > 0) s[k].arc_mm = s[k - 1].arc_mm + (samples[k] - samples[k - 1]).norm();
    if ((samples[k] - ball_centre).norm() < ball_radius) {
      s[k].state = State::Inside;
      continue;
    }
    bool any_inside = false;
    double depth = std::numeric_limits<double>::infinity();    // to the nearest wall it is outside of
    double opening = std::numeric_limits<double>::infinity();  // to the nearest opening it lies beyond
    for (std::size_t n = 0; n < order.size() && !any_inside; ++n) {
      const std::size_t i = order[n];
      const double bound = last_distance[i] + (samples[k] - last_point[i]).norm() + 1e-6;
      const auto at = side(i).classify(samples[k], bound);
      last_distance[i] = at.distance_mm;
      last_point[i] = samples[k];
      if (at.side == geometry::Side::Inside || (at.side == geometry::Side::Outside && at.distance_mm <= kOutsideToleranceMm)) {
        any_inside = true;
        ball_centre = samples[k];
        ball_radius = at.side == geometry::Side::Inside ? side(i).inside_ball_radius_mm(samples[k], at.distance_mm) : 0.0;
        std::rotate(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(n), order.begin() + static_cast<std::ptrdiff_t>(n) + 1);
      } else if (at.side == geometry::Side::BeyondOpening) {
        opening = std::min(opening, at.distance_mm);
      } else if (at.distance_mm < depth) {
        depth = at.distance_mm, s[k].nearest = i;
      }
    }
    // The nearest surface decides: past an opening nearer than any wall, the lumen may go on.
    s[k].state = any_inside ? State::Inside : (depth < opening ? State::Outside : State::Unjudged);
    if (s[k].state == State::Outside && !within_extent(s[k].nearest, samples[k])) s[k].state = State::Unjudged;
    if (s[k].state == State::Outside) s[k].depth_mm = depth;
  }
  out.device_length_mm = s.back().arc_mm;

  // Each segment between samples counts half for each end's state.
  for (std::size_t k = 0; k + 1 < s.size(); ++k) {
    const double half = 0.5 * (s[k + 1].arc_mm - s[k].arc_mm);
    for (const Sample* e : {&s[k], &s[k + 1]})
      if (e->state == State::Unjudged) out.unjudged_length_mm += half;
  }
  for (std::size_t k = 0; k < s.size();) {
    if (s[k].state != State::Outside) {
      ++k;
      continue;
    }
    std::size_t end = k;
    std::size_t deepest = k;
    while (end + 1 < s.size() && s[end + 1].state == State::Outside) {
      ++end;
      if (s[end].depth_mm > s[deepest].depth_mm) deepest = end;
    }
    OutsideStretch stretch;
    // Up to halfway to the neighbouring samples that are not outside.
    stretch.from_mm = k > 0 ? 0.5 * (s[k - 1].arc_mm + s[k].arc_mm) : 0.0;
    stretch.to_mm = end + 1 < s.size() ? 0.5 * (s[end].arc_mm + s[end + 1].arc_mm) : s[end].arc_mm;
    stretch.max_depth_mm = s[deepest].depth_mm;
    stretch.nearest_vessel = vessels[s[deepest].nearest].name;
    out.outside_length_mm += stretch.to_mm - stretch.from_mm;
    out.outside_max_depth_mm = std::max(out.outside_max_depth_mm, stretch.max_depth_mm);
    out.stretches.push_back(std::move(stretch));
    k = end + 1;
  }
  return out;
}

bool leaves_device_outside(const DeviceContainment& c) { return c.outside_max_depth_mm > kWarnDepthMm; }

std::string describe_outside(const DeviceContainment& c) {
  if (c.stretches.empty()) return "";
  const auto deepest = std::max_element(c.stretches.begin(), c.stretches.end(), [](const auto& a, const auto& b) {
    return a.max_depth_mm < b.max_depth_mm;
  });
  char text[320];
  std::snprintf(text, sizeof text,
                "%.1f mm of the device lies outside the vessels, up to %.1f mm beyond the wall of '%s' (from %.1f to "
                "%.1f mm along it%s)",
                c.outside_length_mm, c.outside_max_depth_mm, deepest->nearest_vessel.c_str(), deepest->from_mm,
                deepest->to_mm, c.stretches.size() > 1 ? ", the deepest of its stretches" : "");
  return text;
}

}  // namespace evar::deform
