#include "evar/deform/skeleton.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace evar::deform {

Skeleton build_skeleton(const geometry::RayCaster& caster,
                        const geometry::Polyline& centerline, const SkeletonOptions& options) {
  if (!(options.plane_spacing_mm > 0.0) || options.rays_per_plane < 3)
    throw std::invalid_argument("skeleton: plane spacing must be > 0 and at least 3 rays per plane");
  const auto arc = geometry::arc_lengths(centerline);
  const double length = arc.back();
  // Planes centred in the centerline's extent, half a spacing from each end, so no plane
  // lies in an end cap or an open end.
  const int planes = std::max(1, static_cast<int>(std::floor(length / options.plane_spacing_mm)));
  const double s0 = 0.5 * (length - (planes - 1) * options.plane_spacing_mm);
  geometry::Polyline plane_points;
  std::vector<double> plane_arc;
  for (int k = 0; k < planes; ++k) {
    const double s = s0 + k * options.plane_spacing_mm;
    plane_arc.push_back(s);
    plane_points.push_back(geometry::point_at(centerline, arc, s));
  }
  // Frames that do not twist along the centerline, so the rays of neighbouring planes
  // line up (a twisted skeleton would itself resist the deformation).
  geometry::Polyline frame_path = plane_points;
  if (frame_path.size() == 1) frame_path.push_back(frame_path[0] + geometry::tangent_at(centerline, arc, plane_arc[0]));
  auto frames = geometry::rotation_minimizing_frames(frame_path);
  Skeleton skeleton;
  const double max_ray = 10.0 * std::max(1.0, length);
  for (int k = 0; k < planes; ++k) {
    const Eigen::Vector3d t = geometry::tangent_at(centerline, arc, plane_arc[static_cast<std::size_t>(k)]);
    Eigen::Vector3d n = frames[static_cast<std::size_t>(k)].normal;
    n = (n - n.dot(t) * t);
    if (n.norm() < 1e-9) n = t.unitOrthogonal();
    n.normalize();
    const Eigen::Vector3d b = t.cross(n);
    const Eigen::Vector3d c = plane_points[static_cast<std::size_t>(k)];
    std::vector<Skeleton::Spoke> hits;
    double sum = 0.0;
    for (int r = 0; r < options.rays_per_plane; ++r) {
      const double phi = 2.0 * std::numbers::pi * r / options.rays_per_plane;
      const Eigen::Vector3d dir = std::cos(phi) * n + std::sin(phi) * b;
      const auto hit = caster.first_hit(c, dir, max_ray);
      if (!hit) continue;
      hits.push_back({static_cast<int>(skeleton.centres.size()), hit->face, hit->barycentric, hit->point});
      sum += hit->t_mm;
    }
    if (static_cast<int>(hits.size()) < options.min_hits_per_plane) continue;
    skeleton.centres.push_back(c);
    skeleton.arc_mm.push_back(plane_arc[static_cast<std::size_t>(k)]);
    skeleton.radius_mm.push_back(sum / static_cast<double>(hits.size()));
    skeleton.spokes.insert(skeleton.spokes.end(), hits.begin(), hits.end());
  }
  return skeleton;
}

void append_skeleton_terms(ArapTerms& terms, const geometry::TriangleMesh& mesh, const Skeleton& skeleton,
                           int first_unknown, double weight) {
  const int count = static_cast<int>(skeleton.centres.size());
  if (first_unknown + count > terms.num_unknowns)
    throw std::invalid_argument("skeleton terms: the unknowns do not include the skeleton points");
  std::vector<std::vector<const Skeleton::Spoke*>> by_centre(static_cast<std::size_t>(count));
  for (const auto& s : skeleton.spokes) by_centre[static_cast<std::size_t>(s.centre)].push_back(&s);
  for (int k = 0; k < count; ++k) {
    terms.begin_cell();
    const int ck = first_unknown + k;
    const Eigen::Vector3d& c = skeleton.centres[static_cast<std::size_t>(k)];
    for (const auto* s : by_centre[static_cast<std::size_t>(k)]) {
      // Spoke: centre minus the wall point Σ β_j v_j of the hit triangle.
      std::vector<std::pair<int, double>> coeffs{{ck, 1.0}};
      Eigen::Vector3d hit = Eigen::Vector3d::Zero();
      for (int j = 0; j < 3; ++j) {
        const int v = mesh.F(s->face, j);
        coeffs.emplace_back(v, -s->barycentric[j]);
        hit += s->barycentric[j] * mesh.V.row(v).transpose();
      }
      terms.add_term(weight, coeffs, c - hit);
    }
    for (int nb : {k - 1, k + 1}) {
      if (nb < 0 || nb >= count) continue;
      terms.add_term(weight, {{ck, 1.0}, {first_unknown + nb, -1.0}}, c - skeleton.centres[static_cast<std::size_t>(nb)]);
    }
  }
}

double RadiusProfile::at(double arc) const {
  if (arc_mm.empty()) throw std::logic_error("radius profile is empty");
  if (arc <= arc_mm.front()) return radius_mm.front();
  if (arc >= arc_mm.back()) return radius_mm.back();
  const auto it = std::upper_bound(arc_mm.begin(), arc_mm.end(), arc);
  const auto i = static_cast<std::size_t>(it - arc_mm.begin());
  const double u = (arc - arc_mm[i - 1]) / (arc_mm[i] - arc_mm[i - 1]);
  return (1.0 - u) * radius_mm[i - 1] + u * radius_mm[i];
}

RadiusProfile radius_profile(const Skeleton& skeleton) { return {skeleton.arc_mm, skeleton.radius_mm}; }

}  // namespace evar::deform
