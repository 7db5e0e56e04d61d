#include "evar/prepare/surface_centerlines.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <limits>
#include <optional>
#include <queue>
#include <stdexcept>

#include <Eigen/Geometry>

#include "evar/base/elapsed.hpp"
#include "evar/base/input_error.hpp"
#include "evar/base/quantity_text.hpp"
#include "evar/prepare/surface_split.hpp"
#include "mcf_skeleton.hpp"

namespace evar::prepare {
namespace {

constexpr double kEndStepMm = 1.0;      // spacing of the points an end is run on by
constexpr double kShortOfWallMm = 0.5;  // an end stops this far short of the cap or opening
constexpr int kSmoothingPasses = 3;     // of the skeleton's chains, each (1/4, 1/2, 1/4)
// The aortic inlet's end is at least this much wider than any other end (the aorta's lumen
// is about twice an iliac's across; an aneurysmal iliac can come close).
constexpr double kInletWiderBy = 1.25;
// A skeleton end whose wall lies no farther than its junction's lumen radius plus this
// from the junction is a spur of the flow (a bump of the wall), not a vessel.
constexpr double kSpurMarginMm = 2.0;

struct Skeleton {
  std::vector<Eigen::Vector3d> point;
  std::vector<std::vector<int>> next;
  std::vector<std::vector<int>> mesh_vertices;
  std::vector<double> radius_mm;
};

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// From an end through the chain of two-neighbour points to the first point that is not
// one (included): the end's own vessel, up to where it joins others.
std::vector<int> chain_from(const Skeleton& s, int end) {
  std::vector<int> chain{end};
  int previous = -1, at = end;
  while (chain.size() <= s.point.size()) {
    int step = -1;
    for (const int n : s.next[static_cast<std::size_t>(at)])
      if (n != previous) step = n;
    if (step < 0) break;
    chain.push_back(step);
    if (s.next[static_cast<std::size_t>(step)].size() != 2) break;
    previous = at, at = step;
  }
  return chain;
}

// Whether the end of `chain` (from an end to its junction) leaves the junction the way
// another of its branches does (within 45°, each branch's direction taken about
// `radius_mm` along it; branches dropped as spurs and branches that end inside that radius
// do not count): the flow's leftovers near a junction point along the vessels that
// leave it, while a vessel's own end leaves in a direction no other branch takes, even one
// the flow pulled back inside the junction's lumen (a short, wide aorta above the renal
// arteries).
bool repeats_a_branch(const Skeleton& s, const std::vector<int>& chain, double radius_mm, const std::vector<char>& dropped) {
  const auto junction = static_cast<std::size_t>(chain.back());
  const Eigen::Vector3d& centre = s.point[junction];
  const Eigen::Vector3d own = (s.point[static_cast<std::size_t>(chain.front())] - centre).normalized();
  const int own_first = chain[chain.size() - 2];
  for (const int first : s.next[junction]) {
    if (first == own_first || dropped[static_cast<std::size_t>(first)]) continue;
    int previous = static_cast<int>(junction), at = first;
    while ((s.point[static_cast<std::size_t>(at)] - centre).norm() < radius_mm && s.next[static_cast<std::size_t>(at)].size() == 2) {
      const auto& two = s.next[static_cast<std::size_t>(at)];
      const int step = two[0] == previous ? two[1] : two[0];
      previous = at, at = step;
    }
    // Only a branch that leaves the lumen counts: two ends both inside it (a vessel's end
    // pulled back and a leftover beside it) would otherwise each repeat the other.
    const Eigen::Vector3d branch = s.point[static_cast<std::size_t>(at)] - centre;
    if (branch.norm() >= radius_mm && branch.normalized().dot(own) > std::cos(std::numbers::pi / 4.0)) return true;
  }
  return false;
}

// How far the surface goes on from `origin` along the unit direction `t`: to the wall the
// ray meets (a cap), or, out through an opening, to its rim: the farthest along `t` of the
// mesh vertices that collapsed onto the skeleton points `tail`.
double room_past(const Skeleton& s, const std::vector<int>& tail, const Eigen::Vector3d& origin, const Eigen::Vector3d& t,
                 const geometry::RayCaster& walls) {
  double rim = 0.0;
  const auto& V = walls.mesh().V;
  for (const int k : tail)
    for (const int v : s.mesh_vertices[static_cast<std::size_t>(k)])
      rim = std::max(rim, (V.row(v).transpose() - origin).dot(t));
  // A ray out through an opening may meet another vessel from outside: a hit beyond the
  // collapsed vertices' reach (and a millimetre) is not this vessel's cap.
  if (const auto hit = walls.first_hit(origin, t); hit && (rim <= 0.0 || hit->t_mm <= rim + 1.0)) return hit->t_mm;
  return rim;
}

// The centre of the lumen's cross-section through `q` square to the unit direction `t`:
// the mean of the chords' midpoints along four directions 45 degrees apart, each the
// projection of the centre onto its chord, so twice their mean offset is the centre's (exact
// for a circle). Nothing where a chord finds no wall (out past an opening). `half_chord_mm`:
// the chords' mean half length (the lumen's radius there).
std::optional<Eigen::Vector3d> cross_section_centre(const Eigen::Vector3d& q, const Eigen::Vector3d& t,
                                                    const geometry::RayCaster& walls, double& half_chord_mm) {
  const Eigen::Vector3d u = t.unitOrthogonal(), v = t.cross(u);
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  half_chord_mm = 0.0;
  for (int k = 0; k < 4; ++k) {
    const double angle = M_PI / 4.0 * k;
    const Eigen::Vector3d d = std::cos(angle) * u + std::sin(angle) * v;
    const auto ahead = walls.first_hit(q, d), behind = walls.first_hit(q, -d);
    if (!ahead || !behind) return std::nullopt;
    offset += 0.5 * (ahead->t_mm - behind->t_mm) * d;
    half_chord_mm += 0.125 * (ahead->t_mm + behind->t_mm);
  }
  return q + 2.0 * offset / 4.0;
}

// The end of `path` (skeleton indices, ending at a skeleton end), made to run to the cap or
// opening along the lumen's centre: the flow's last stretch within a lumen radius of its end
// is dropped from `path` (there it may curl toward a rim or a corner of a flat cap); the
// points returned run on from what is left, in the direction of its last two radii, each
// moved to the centre of the lumen's cross-section, and within half a radius of the cap
// (where the chords would reach the cap) by the last such move.
geometry::Polyline run_on(const Skeleton& s, std::vector<int>& path, const geometry::RayCaster& walls) {
  const auto at = [&](std::size_t k) { return s.point[static_cast<std::size_t>(path[k])]; };
  const auto radius = [&](std::size_t k) { return s.radius_mm[static_cast<std::size_t>(path[k])]; };
  std::size_t last = path.size() - 1;
  while (last > 1 && (at(last) - at(path.size() - 1)).norm() < radius(last)) --last;
  std::size_t from = last;
  while (from > 0 && (at(from) - at(last)).norm() < std::max(2.0, 2.0 * radius(last))) --from;
  const std::vector<int> tail(path.begin() + static_cast<std::ptrdiff_t>(from), path.end());
  const Eigen::Vector3d end = at(last), direction = end - at(from);
  path.resize(last + 1);
  geometry::Polyline more;
  if (direction.norm() < 1e-9) return more;
  const Eigen::Vector3d t = direction.normalized();
  const double room = room_past(s, tail, end, t, walls) - kShortOfWallMm;
  Eigen::Vector3d shift = Eigen::Vector3d::Zero();
  const auto centred = [&](double d) {
    const Eigen::Vector3d q = end + d * t;
    double half_chord = 0.0;
    if (const auto c = cross_section_centre(q, t, walls, half_chord); c && room - d >= 0.5 * half_chord) shift = *c - q;
    return Eigen::Vector3d(q + shift);
  };
  for (double d = kEndStepMm; d < room; d += kEndStepMm) more.push_back(centred(d));
  if (room > 0.0) more.push_back(centred(room));
  return more;
}

}  // namespace

SurfaceCenterlines centerlines_from_surface(const geometry::TriangleMesh& surface, const geometry::RayCaster& walls,
                                            const std::string& source) {
  const auto t0 = std::chrono::steady_clock::now();
  SurfaceCenterlines out;
  SkeletonGraph graph;
  try {
    graph = mean_curvature_flow_skeleton(surface);
  } catch (const std::invalid_argument& e) {
    throw base::InputError(source + ": its centerlines cannot be computed from the surface (" + e.what() +
                           "); repair the surface (3D Slicer: Segment Editor's Smoothing, then export again) or give "
                           "its centerlines with --centerlines");
  }
  out.openings_closed = graph.holes_closed;
  out.skeleton_points = static_cast<int>(graph.points.size());

  for (const auto& p : graph.points)
    if (!p.allFinite())
      throw base::InputError(source + ": its centerlines cannot be computed from the surface (the skeleton's flow "
                                      "diverged); give them with --centerlines");
  Skeleton s;
  const std::size_t n = graph.points.size();
  s.point = graph.points;
  s.mesh_vertices = std::move(graph.mesh_vertices);
  s.next.resize(n);
  for (const auto& [a, b] : graph.edges)
    if (a != b) s.next[static_cast<std::size_t>(a)].push_back(b), s.next[static_cast<std::size_t>(b)].push_back(a);
  // The flow leaves its chains a little jagged on a staircase surface: smooth them, ends
  // and junctions held.
  for (int pass = 0; pass < kSmoothingPasses; ++pass) {
    auto smoothed = s.point;
    for (std::size_t i = 0; i < n; ++i)
      if (s.next[i].size() == 2)
        smoothed[i] = 0.5 * s.point[i] +
                      0.25 * (s.point[static_cast<std::size_t>(s.next[i][0])] + s.point[static_cast<std::size_t>(s.next[i][1])]);
    s.point = std::move(smoothed);
  }
  s.radius_mm = radius_from_surface(walls, s.point);

  // The ends, spurs dropped until none is left (a flat cap's skeleton may fork into two
  // spurs, whose junction is then the end); the aortic inlet is the end of the widest vessel.
  std::vector<char> dropped(n, 0);
  for (bool pruned = true; pruned;) {
    pruned = false;
    for (std::size_t i = 0; i < n; ++i) {
      if (dropped[i] || s.next[i].size() != 1) continue;
      const auto chain = chain_from(s, static_cast<int>(i));
      const auto junction = static_cast<std::size_t>(chain.back());
      if (s.next[junction].size() < 3) continue;
      // A spur: the end lies inside the lumen round its junction along another branch (the
      // flow's leftovers, often a point or two), or the wall is no farther than that lumen
      // beyond it.
      const double reach = (s.point[i] - s.point[junction]).norm();
      const bool spur = (reach < s.radius_mm[junction] && repeats_a_branch(s, chain, s.radius_mm[junction], dropped)) ||
                        reach + room_past(s, chain, s.point[i], (s.point[i] - s.point[junction]).normalized(), walls) <=
                            s.radius_mm[junction] + kSpurMarginMm;
      if (!spur) continue;
      for (std::size_t k = 0; k + 1 < chain.size(); ++k) dropped[static_cast<std::size_t>(chain[k])] = 1;
      ++out.spurs_dropped;
      pruned = true;
    }
    // Their junctions become points of the chain they sat on (or an end).
    for (std::size_t i = 0; i < n; ++i)
      std::erase_if(s.next[i], [&](int m) { return dropped[static_cast<std::size_t>(m)] != 0; });
  }
  // The skeleton in one piece: a surface in several (a stray island of the segmentation)
  // gives one skeleton per piece.
  std::vector<int> piece(n, -1);
  int pieces = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (dropped[i] || piece[i] >= 0 || s.next[i].empty()) continue;
    std::vector<int> todo{static_cast<int>(i)};
    piece[i] = pieces;
    while (!todo.empty()) {
      const int at = todo.back();
      todo.pop_back();
      for (const int m : s.next[static_cast<std::size_t>(at)])
        if (piece[static_cast<std::size_t>(m)] < 0) piece[static_cast<std::size_t>(m)] = pieces, todo.push_back(m);
    }
    ++pieces;
  }
  if (pieces > 1)
    throw base::InputError(source + ": no centerlines given, and the surface is in " + std::to_string(pieces) +
                           " separate pieces (its skeleton is): keep only the aorto-iliac one (3D Slicer: Segment "
                           "Editor, Islands, keep the largest) or give its centerlines with --centerlines");
  std::vector<int> ends;
  for (std::size_t i = 0; i < n; ++i)
    if (!dropped[i] && s.next[i].size() == 1) ends.push_back(static_cast<int>(i));
  if (ends.size() < 3)
    throw base::InputError(source + ": no centerlines given, and the surface's skeleton has " + std::to_string(ends.size()) +
                           (ends.size() == 1 ? " end" : " ends") +
                           " where an aorto-iliac bifurcation has three or more (the aortic inlet, both iliac outlets, "
                           "any side-branch stubs): is the surface the aorta and both iliacs in one connected piece? "
                           "Otherwise give its centerlines with --centerlines");
  // Width across the vessel (the cross-section's half chords, square to the chain), not
  // the distance to the nearest wall, which near a cap is the cap's: a segmentation cropped
  // just above the renal arteries leaves the aorta's own chain a few millimetres long.
  std::vector<std::pair<double, int>> widths;  // (width, end), widest first
  for (const int e : ends) {
    const auto chain = chain_from(s, e);
    std::vector<double> r;
    for (std::size_t k = 0; k < chain.size(); ++k) {
      const Eigen::Vector3d along = s.point[static_cast<std::size_t>(chain[std::min(k + 1, chain.size() - 1)])] -
                                    s.point[static_cast<std::size_t>(chain[k > 0 ? k - 1 : 0])];
      double half_chord = 0.0;
      if (along.norm() > 1e-9 &&
          cross_section_centre(s.point[static_cast<std::size_t>(chain[k])], along.normalized(), walls, half_chord))
        r.push_back(half_chord);
    }
    widths.emplace_back(median(r), e);
  }
  std::sort(widths.begin(), widths.end(), std::greater<>());
  // The aorta is the widest vessel by far at its end; an end no wider than the next is no
  // inlet to trust (the aorta's end collapsed into a branch point: cropped just above the
  // renal arteries; or an iliac as wide as the aorta).
  if (!(widths[0].first > 0.0 && widths[0].first >= kInletWiderBy * widths[1].first)) {
    throw base::InputError(
        source + ": no centerlines given, and the surface's skeleton has no end clearly wider than the others to be "
                 "the aortic inlet (the two widest ends are " + base::quantity_text(2.0 * widths[0].first, "mm", 0) +
        " and " + base::quantity_text(2.0 * widths[1].first, "mm", 0) +
        " across): the segmentation may stop within a few millimetres above the renal arteries (segment the aorta on for at least "
        "its diameter above its highest branch), or an iliac is as wide as the aorta. Give its centerlines with "
        "--centerlines (VMTK's vmtkcenterlines, or 3D Slicer's Extract Centerline)");
  }
  const int inlet = widths[0].second;

  // Shortest paths from the inlet along the skeleton (a surface with a handle gives a
  // skeleton with a loop; the shorter way round is taken).
  std::vector<double> dist(n, std::numeric_limits<double>::infinity());
  std::vector<int> parent(n, -1);
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
  dist[static_cast<std::size_t>(inlet)] = 0.0;
  queue.push({0.0, inlet});
  while (!queue.empty()) {
    const auto [d, at] = queue.top();
    queue.pop();
    if (d > dist[static_cast<std::size_t>(at)]) continue;
    for (const int m : s.next[static_cast<std::size_t>(at)]) {
      const double via = d + (s.point[static_cast<std::size_t>(m)] - s.point[static_cast<std::size_t>(at)]).norm();
      if (via < dist[static_cast<std::size_t>(m)]) {
        dist[static_cast<std::size_t>(m)] = via, parent[static_cast<std::size_t>(m)] = at;
        queue.push({via, m});
      }
    }
  }

  // The inlet's end is made once, shared by every path.
  auto toward_inlet = chain_from(s, inlet);
  std::reverse(toward_inlet.begin(), toward_inlet.end());
  const std::size_t inlet_chain = toward_inlet.size();
  geometry::Polyline inlet_run = run_on(s, toward_inlet, walls);
  std::reverse(inlet_run.begin(), inlet_run.end());
  const std::vector<double> inlet_run_radius = radius_from_surface(walls, inlet_run);
  const std::size_t inlet_dropped = inlet_chain - toward_inlet.size();
  // One path per other end (the skeleton is in one piece: every end is reached).
  for (const int e : ends) {
    if (e == inlet) continue;
    std::vector<int> path;
    for (int k = e; k >= 0; k = parent[static_cast<std::size_t>(k)]) path.push_back(k);
    std::reverse(path.begin(), path.end());
    path.erase(path.begin(), path.begin() + static_cast<std::ptrdiff_t>(std::min(inlet_dropped, path.size() - 2)));
    const geometry::Polyline outlet_run = run_on(s, path, walls);
    const std::vector<double> outlet_run_radius = radius_from_surface(walls, outlet_run);
    geometry::CenterlineCurve curve;
    curve.points = inlet_run;
    curve.radius_mm = inlet_run_radius;
    for (const int k : path) {
      curve.points.push_back(s.point[static_cast<std::size_t>(k)]);
      curve.radius_mm.push_back(s.radius_mm[static_cast<std::size_t>(k)]);
    }
    curve.points.insert(curve.points.end(), outlet_run.begin(), outlet_run.end());
    curve.radius_mm.insert(curve.radius_mm.end(), outlet_run_radius.begin(), outlet_run_radius.end());
    out.paths.push_back(std::move(curve));
  }
  out.skeleton_ms = base::ms_since(t0);
  return out;
}

}  // namespace evar::prepare
