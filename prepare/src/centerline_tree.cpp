#include "evar/prepare/centerline_tree.hpp"

#include <algorithm>
#include <cstdio>
#include <limits>
#include <map>
#include <numeric>

#include "evar/base/input_error.hpp"
#include "evar/base/quantity_text.hpp"

namespace evar::prepare {
namespace {

constexpr double kSamePointMm = 1.5;  // ends of curves this close are one point
constexpr double kPartedMm = 0.5;     // paths farther apart than this have parted

[[noreturn]] void refuse(const std::string& source, const std::string& why) {
  throw base::InputError(source + ": " + why);
}

// `b` appended to `a`, without b's first point where it repeats a's last; radii kept only
// when both have them.
void append(geometry::CenterlineCurve& a, const geometry::CenterlineCurve& b) {
  const bool radii = a.radius_mm.size() == a.points.size() && b.radius_mm.size() == b.points.size();
  const std::ptrdiff_t from =
      !a.points.empty() && !b.points.empty() && (a.points.back() - b.points.front()).norm() < 1e-6 ? 1 : 0;
  a.points.insert(a.points.end(), b.points.begin() + from, b.points.end());
  if (radii)
    a.radius_mm.insert(a.radius_mm.end(), b.radius_mm.begin() + from, b.radius_mm.end());
  else
    a.radius_mm.clear();
}

}  // namespace

std::vector<geometry::CenterlineCurve> centerline_paths(const std::vector<geometry::CenterlineCurve>& input,
                                                       const std::string& source) {
  std::vector<geometry::CenterlineCurve> curves;
  for (const auto& c : input)
    if (c.points.size() >= 2) curves.push_back(c);
  if (curves.empty()) refuse(source, "holds no curve of two or more points");

  // VMTK branch pieces: one path per CenterlineIds value, its tracts in TractIds order.
  if (std::all_of(curves.begin(), curves.end(), [](const auto& c) {
        return c.cell_values.count("CenterlineIds") && c.cell_values.count("TractIds");
      })) {
    std::map<long long, std::vector<const geometry::CenterlineCurve*>> by_path;
    for (const auto& c : curves) by_path[c.cell_values.at("CenterlineIds")].push_back(&c);
    std::vector<geometry::CenterlineCurve> paths;
    for (auto& [id, pieces] : by_path) {
      std::sort(pieces.begin(), pieces.end(),
                [](const auto* a, const auto* b) { return a->cell_values.at("TractIds") < b->cell_values.at("TractIds"); });
      geometry::CenterlineCurve path;
      path.radius_mm = pieces.front()->radius_mm;
      path.points = pieces.front()->points;
      for (std::size_t k = 1; k < pieces.size(); ++k) append(path, *pieces[k]);
      path.cell_values["CenterlineIds"] = id;
      paths.push_back(std::move(path));
    }
    return paths;
  }

  // Paths already: every curve starts where the first does.
  if (std::all_of(curves.begin(), curves.end(), [&](const auto& c) {
        return (c.points.front() - curves.front().points.front()).norm() < kSamePointMm;
      }))
    return curves;

  // A tree of curves chained end to start.
  const std::size_t n = curves.size();
  std::vector<int> parent(n, -1);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j)
      if (i != j && (curves[i].points.front() - curves[j].points.back()).norm() < kSamePointMm) {
        if (parent[i] >= 0)
          refuse(source, "curve " + std::to_string(i + 1) + " starts at the end of two others; a centerline tree "
                         "continues each branch from one parent");
        parent[i] = static_cast<int>(j);
      }
  std::vector<std::size_t> roots;
  for (std::size_t i = 0; i < n; ++i)
    if (parent[i] < 0) roots.push_back(i);
  if (roots.size() != 1)
    refuse(source, "its " + std::to_string(n) + " curves make " + std::to_string(roots.size()) +
                       " separate trees (each curve must start where the curve it branches from ends, within " +
                       base::quantity_text(kSamePointMm, "mm", 1) + ", or all must start at the inlet)");
  std::vector<geometry::CenterlineCurve> paths;
  for (std::size_t leaf = 0; leaf < n; ++leaf) {
    if (std::find(parent.begin(), parent.end(), static_cast<int>(leaf)) != parent.end()) continue;
    std::vector<std::size_t> chain{leaf};
    while (parent[chain.back()] >= 0) {
      chain.push_back(static_cast<std::size_t>(parent[chain.back()]));
      if (chain.size() > n) refuse(source, "its curves run in a loop (each continues another)");
    }
    geometry::CenterlineCurve path = curves[chain.back()];
    for (auto it = chain.rbegin() + 1; it != chain.rend(); ++it) append(path, curves[*it]);
    paths.push_back(std::move(path));
  }
  return paths;
}

BifurcationTree bifurcation_tree(const std::vector<geometry::CenterlineCurve>& all_paths, const std::string& source) {
  if (all_paths.size() < 2)
    refuse(source, "holds " + std::to_string(all_paths.size()) +
                       " centerline path; an aorto-iliac scene needs two, from the aortic inlet to each iliac outlet");
  BifurcationTree tree;
  // The iliacs: the two outlets farthest from the inlet.
  std::vector<std::size_t> order(all_paths.size());
  std::iota(order.begin(), order.end(), 0);
  const Eigen::Vector3d inlet = all_paths.front().points.front();
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return (all_paths[a].points.back() - inlet).norm() > (all_paths[b].points.back() - inlet).norm();
  });
  const auto& A = all_paths[order[0]];
  const auto& B = all_paths[order[1]];
  if (all_paths.size() > 2)
    tree.note = "of its " + std::to_string(all_paths.size()) + " centerline paths, the two whose outlets lie farthest "
                "from the inlet (paths " + std::to_string(order[0] + 1) + " and " + std::to_string(order[1] + 1) +
                ") are taken as the iliacs";
  if ((A.points.front() - B.points.front()).norm() > kSamePointMm)
    refuse(source, "its iliac paths start " + base::quantity_text((A.points.front() - B.points.front()).norm(), "mm", 1) +
                       " apart; both must start at the aortic inlet");

  // Where A parts from B.
  const geometry::PolylineProjector onto_b(B.points);
  std::size_t part = A.points.size();
  int segment = -1;
  for (std::size_t k = 0; k < A.points.size(); ++k)
    if (onto_b.project(A.points[k], segment, &segment).distance_mm > kPartedMm) {
      part = k;
      break;
    }
  if (part == A.points.size() || part < 2)
    refuse(source, part < 2 ? "its iliac paths part at the inlet: the aortic trunk is missing"
                            : "its two longest paths never part: they are the same vessel, not the two iliacs");
  const std::size_t fork = part - 1;  // the last shared point
  tree.trunk.assign(A.points.begin(), A.points.begin() + static_cast<std::ptrdiff_t>(fork) + 1);
  if (A.radius_mm.size() == A.points.size())
    tree.trunk_radius_mm.assign(A.radius_mm.begin(), A.radius_mm.begin() + static_cast<std::ptrdiff_t>(fork) + 1);
  tree.branches[0].assign(A.points.begin() + static_cast<std::ptrdiff_t>(fork), A.points.end());
  if (A.radius_mm.size() == A.points.size())
    tree.branch_radius_mm[0].assign(A.radius_mm.begin() + static_cast<std::ptrdiff_t>(fork), A.radius_mm.end());
  // B from its point nearest the fork.
  std::size_t from = 0;
  double nearest = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < B.points.size(); ++k)
    if (const double d = (B.points[k] - A.points[fork]).norm(); d < nearest) nearest = d, from = k;
  tree.branches[1].assign(B.points.begin() + static_cast<std::ptrdiff_t>(from), B.points.end());
  if (B.radius_mm.size() == B.points.size())
    tree.branch_radius_mm[1].assign(B.radius_mm.begin() + static_cast<std::ptrdiff_t>(from), B.radius_mm.end());
  if (tree.branches[1].size() < 2) refuse(source, "one iliac path ends where the paths part");

  // Side branches: every other path, from where it parts from the iliac paths.
  const geometry::PolylineProjector onto_a(A.points);
  for (std::size_t n = 2; n < order.size(); ++n) {
    const auto& P = all_paths[order[n]];
    std::size_t leave = P.points.size();
    int sa = -1, sb = -1;
    for (std::size_t k = 0; k < P.points.size(); ++k)
      if (onto_a.project(P.points[k], sa, &sa).distance_mm > kPartedMm &&
          onto_b.project(P.points[k], sb, &sb).distance_mm > kPartedMm) {
        leave = k;
        break;
      }
    if (leave == 0 || leave >= P.points.size()) continue;  // not a branch of this tree
    const Eigen::Vector3d parting = P.points[leave - 1];
    // The parent: the trunk or the iliac branch nearest the parting point.
    SideBranch side;
    const geometry::Polyline* parent = &tree.trunk;
    const std::vector<double>* parent_radius = &tree.trunk_radius_mm;
    double nearest = geometry::project_onto(tree.trunk, parting).distance_mm;
    for (int b = 0; b < 2; ++b) {
      const double d = geometry::project_onto(tree.branches[static_cast<std::size_t>(b)], parting).distance_mm;
      const bool below_fork = geometry::project_onto(tree.trunk, parting).beyond_end;
      if (below_fork && d <= nearest + 1e-9) {
        nearest = d, side.parent = b;
        parent = &tree.branches[static_cast<std::size_t>(b)];
        parent_radius = &tree.branch_radius_mm[static_cast<std::size_t>(b)];
      }
    }
    side.leaves_parent = parting;
    const auto parent_arc = geometry::arc_lengths(*parent);
    for (std::size_t k = leave; k < P.points.size(); ++k) {
      const auto at = geometry::project_onto(*parent, P.points[k]);
      double r = 0.0;
      if (parent_radius->size() == parent->size()) {
        const auto j = static_cast<std::size_t>(std::upper_bound(parent_arc.begin(), parent_arc.end(), at.arc_length_mm) -
                                                parent_arc.begin());
        r = (*parent_radius)[std::min(j, parent->size()) - (j > 0 ? 1 : 0)];
      }
      side.leaves_parent = P.points[k];
      if (at.distance_mm >= r) break;
    }
    side.outlet = P.points.back();
    tree.side_branches.push_back(side);
  }
  return tree;
}

}  // namespace evar::prepare
