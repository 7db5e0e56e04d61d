#include "section_sweep.hpp"

#include <algorithm>
#include <stdexcept>

namespace evar::sim::detail {

std::vector<Eigen::Vector3d> point_tangents(const geometry::Polyline& c) {
  std::vector<Eigen::Vector3d> t(c.size(), Eigen::Vector3d::UnitZ());
  for (std::size_t i = 0; i < c.size(); ++i) {
    const Eigen::Vector3d d = c[std::min(i + 1, c.size() - 1)] - c[i > 0 ? i - 1 : 0];
    if (d.norm() > 1e-12) t[i] = d.normalized();
    else if (i > 0) t[i] = t[i - 1];
  }
  return t;
}

SectionSweep::SectionSweep(const geometry::Polyline& from, const geometry::Polyline& to)
    : from_(from), to_(to), projector_(from), arc_(geometry::arc_lengths(from)) {
  if (from.size() != to.size() || from.size() < 2)
    throw std::invalid_argument("resweep: the moved centerline needs the same (>= 2) points");
}

SectionSweep::SectionSweep(const geometry::Polyline& from, const geometry::Polyline& to, const std::vector<double>& turn)
    : SectionSweep(from, to) {
  if (turn.size() != from.size()) throw std::invalid_argument("resweep: one turn share per centerline point");
  const auto t0 = point_tangents(from), t1 = point_tangents(to);
  for (std::size_t i = 0; i < from.size(); ++i)
    turn_.push_back(Eigen::Quaterniond::Identity().slerp(turn[i], Eigen::Quaterniond::FromTwoVectors(t0[i], t1[i])));
}

Eigen::Vector3d SectionSweep::map(const Eigen::Vector3d& x, int* hint) const {
  int segment = 0;
  const auto proj = projector_.project(x, *hint, &segment);
  *hint = segment;
  const auto j = static_cast<std::size_t>(segment);
  const double len = arc_[j + 1] - arc_[j];
  const double f = len > 0.0 ? std::clamp((proj.arc_length_mm - arc_[j]) / len, 0.0, 1.0) : 0.0;
  if (turn_.empty()) return x + (1.0 - f) * (to_[j] - from_[j]) + f * (to_[j + 1] - from_[j + 1]);
  const Eigen::Vector3d centre = (1.0 - f) * from_[j] + f * from_[j + 1];
  const Eigen::Vector3d moved = (1.0 - f) * to_[j] + f * to_[j + 1];
  return moved + turn_[j].slerp(f, turn_[j + 1]) * (x - centre);
}

geometry::TriangleMesh SectionSweep::map(const geometry::TriangleMesh& mesh) const {
  geometry::TriangleMesh out = mesh;
  int hint = -1;
  for (Eigen::Index v = 0; v < mesh.V.rows(); ++v) out.V.row(v) = map(Eigen::Vector3d(mesh.V.row(v).transpose()), &hint).transpose();
  return out;
}

}  // namespace evar::sim::detail
