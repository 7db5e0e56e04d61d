#include "ordered_pairing.hpp"

#include "evar/deform/skeleton.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace evar::deform {
namespace {

// The skeleton's plane spacing (paper 2.2): a vessel's end is not resolved more finely.
constexpr double kSkeletonSpacingMm = SkeletonOptions{}.plane_spacing_mm;

// The non-decreasing sequence closest to `y` in least squares (pool adjacent violators).
void make_non_decreasing(std::vector<double>& y) {
  struct Block {
    double mean;
    int size;
  };
  std::vector<Block> blocks;
  for (const double v : y) {
    blocks.push_back({v, 1});
    while (blocks.size() >= 2 && blocks[blocks.size() - 2].mean > blocks.back().mean) {
      const Block last = blocks.back();
      blocks.pop_back();
      Block& prev = blocks.back();
      prev.mean = (prev.mean * prev.size + last.mean * last.size) / (prev.size + last.size);
      prev.size += last.size;
    }
  }
  std::size_t k = 0;
  for (const Block& b : blocks)
    for (int j = 0; j < b.size; ++j) y[k++] = b.mean;
}

// Pairs sections from `entry_arc` (along `centerline`) distally with `forward`, a device
// given proximal end first whose first point is the entry section's partner.
std::vector<SectionPartner> pair_forward(const geometry::Polyline& centerline, const std::vector<double>& centerline_arc,
                                         geometry::Polyline forward, double entry_arc, double step_mm) {
  const double device_length = geometry::arc_lengths(forward).back();
  const double vessel_end = centerline_arc.back();
  if (!(device_length > 0.0) || !(vessel_end - entry_arc > 0.0)) return {};
  // Where the device's distal end reaches the vessel's (its foot within the last skeleton
  // spacing of the centerline, or past it), the access holds the vessel's end: sections
  // beyond the device's length are held at its end. Otherwise the device continues toward
  // the access out of the field of view: straight on, as a stiff wire runs, for as far as
  // the vessel could still reach, and sections whose partner lies on that unseen part get
  // none.
  const geometry::PolylineProjection end_foot = geometry::project_onto(centerline, forward.back());
  const bool reaches_end = end_foot.beyond_end || end_foot.arc_length_mm > vessel_end - kSkeletonSpacingMm;
  if (!reaches_end) {
    const Eigen::Vector3d tip = forward.back();
    Eigen::Vector3d along = Eigen::Vector3d::Zero();
    for (auto it = forward.rbegin() + 1; it != forward.rend() && along.norm() < step_mm; ++it) along = tip - *it;
    if (along.norm() > 0.0) forward.push_back(tip + along.normalized() * (2.0 * (vessel_end - entry_arc) + step_mm));
  }
  // Sections evenly spaced, at most step_mm apart, from the entry to the vessel's end.
  const int count = static_cast<int>(std::ceil((vessel_end - entry_arc) / step_mm - 1e-9)) + 1;
  const double h = (vessel_end - entry_arc) / (count - 1);
  std::vector<double> shortest(static_cast<std::size_t>(count));
  const geometry::PolylineProjector onto_device(forward);
  int device_segment = -1;
  for (int k = 0; k < count; ++k)
    shortest[static_cast<std::size_t>(k)] =
        onto_device
            .project(geometry::point_at(centerline, centerline_arc, entry_arc + k * h), device_segment, &device_segment)
            .arc_length_mm;
  make_non_decreasing(shortest);
  // Sliding keeps each section's arc from the entry.
  std::vector<SectionPartner> pairs;
  for (int k = 0; k < count; ++k) {
    const double sliding = k * h, shortest_k = shortest[static_cast<std::size_t>(k)];
    if (reaches_end) {
      pairs.push_back({entry_arc + k * h, 0.5 * (std::min(shortest_k, device_length) + std::min(sliding, device_length))});
      continue;
    }
    const double partner = 0.5 * (shortest_k + sliding);
    if (partner > device_length) break;
    pairs.push_back({entry_arc + k * h, partner});
  }
  if (pairs.size() < 5) return {};
  return pairs;
}

}  // namespace

std::vector<SectionPartner> ordered_pairing(const geometry::Polyline& centerline, const geometry::Polyline& device,
                                            double step_mm) {
  if (!(step_mm > 0.0)) throw std::invalid_argument("ordered pairing: the step must be > 0");
  if (centerline.size() < 2 || device.size() < 2) return {};
  const auto centerline_arc = geometry::arc_lengths(centerline);
  const geometry::PolylineProjector onto_centerline(centerline);
  int segment = -1;
  const double first = onto_centerline.project(device.front(), segment, &segment).arc_length_mm;
  const double last = onto_centerline.project(device.back(), segment, &segment).arc_length_mm;
  if (std::abs(last - first) < 4.0 * step_mm) return {};  // across the vessel, not along it
  // Worked on with the device's proximal end first; its arcs are mapped back at the end.
  const bool proximal_first = first <= last;
  geometry::Polyline forward(device);
  if (!proximal_first) std::reverse(forward.begin(), forward.end());
  auto pairs = pair_forward(centerline, centerline_arc, std::move(forward), std::min(first, last), step_mm);
  if (!proximal_first) {
    const double device_length = geometry::arc_lengths(device).back();
    for (auto& p : pairs) p.device_arc_mm = device_length - p.device_arc_mm;
    std::reverse(pairs.begin(), pairs.end());
  }
  return pairs;
}

geometry::Polyline device_run_from(const geometry::Polyline& centerline, const geometry::Polyline& device,
                                   const Eigen::Vector3d& entry, double step_mm) {
  if (!(step_mm > 0.0)) throw std::invalid_argument("device run: the step must be > 0");
  if (centerline.size() < 2 || device.size() < 2) return {};
  const geometry::Polyline samples = geometry::resample_symmetric(device, step_mm);
  if (samples.size() < 2) return {};
  std::size_t at = 0;
  for (std::size_t i = 1; i < samples.size(); ++i)
    if ((samples[i] - entry).squaredNorm() < (samples[at] - entry).squaredNorm()) at = i;
  if (at == 0 || at + 1 == samples.size()) return {};  // it does not pass the entry
  const geometry::PolylineProjector onto_centerline(centerline);
  const bool forward = onto_centerline.project(samples.back()).arc_length_mm >=
                       onto_centerline.project(samples.front()).arc_length_mm;
  // The first section is a cross-section: its partner is where the device crosses its
  // plane (through the entry, normal to the centerline's start), at the crossing next to
  // the device's point nearest the entry along the device; where the device passes
  // off-centre and obliquely that lies some way along it. Without a crossing the nearest
  // point stands.
  const auto arc = geometry::arc_lengths(centerline);
  const Eigen::Vector3d normal = geometry::tangent_at(centerline, arc, 0.0);
  Eigen::Vector3d first = samples[at];
  std::size_t next = forward ? at + 1 : at - 1;  // the first sample after the crossing
  std::size_t best = samples.size();             // index distance of the crossing found
  for (std::size_t i = 0; i + 1 < samples.size(); ++i) {
    const double a = (samples[i] - entry).dot(normal), b = (samples[i + 1] - entry).dot(normal);
    if ((a > 0.0) == (b > 0.0) || a == b) continue;
    const std::size_t apart = i < at ? at - i : i - at;
    if (apart >= best) continue;
    best = apart;
    first = samples[i] + a / (a - b) * (samples[i + 1] - samples[i]);
    next = forward ? i + 1 : i;
  }
  geometry::Polyline run{first};
  int segment = -1;
  const auto take = [&](auto begin, auto end) {
    for (auto it = begin; it != end; ++it) {
      if (onto_centerline.project(*it, segment, &segment).beyond_end) break;
      if ((*it - run.back()).squaredNorm() > 0.0) run.push_back(*it);
    }
  };
  if (forward)
    take(samples.begin() + static_cast<std::ptrdiff_t>(next), samples.end());
  else
    take(samples.rbegin() + static_cast<std::ptrdiff_t>(samples.size() - 1 - next), samples.rend());
  return run.size() >= 2 ? run : geometry::Polyline{};
}

std::vector<SectionPartner> ordered_pairing_from_entry(const geometry::Polyline& centerline, const geometry::Polyline& run,
                                                       double step_mm) {
  if (!(step_mm > 0.0)) throw std::invalid_argument("ordered pairing: the step must be > 0");
  if (centerline.size() < 2 || run.size() < 2) return {};
  return pair_forward(centerline, geometry::arc_lengths(centerline), run, 0.0, step_mm);
}

double section_arc_of(const std::vector<SectionPartner>& pairs, double device_arc_mm) {
  if (pairs.empty()) throw std::invalid_argument("ordered pairing: no pairs to invert");
  const auto by_device = [](const SectionPartner& p, double a) { return p.device_arc_mm < a; };
  const auto lo = std::lower_bound(pairs.begin(), pairs.end(), device_arc_mm, by_device);
  const auto hi = std::upper_bound(pairs.begin(), pairs.end(), device_arc_mm,
                                   [](double a, const SectionPartner& p) { return a < p.device_arc_mm; });
  if (lo != hi) {
    double sum = 0.0;
    for (auto it = lo; it != hi; ++it) sum += it->section_arc_mm;
    return sum / static_cast<double>(hi - lo);
  }
  if (lo == pairs.begin()) return pairs.front().section_arc_mm;
  if (lo == pairs.end()) return pairs.back().section_arc_mm;
  const auto& a = *(lo - 1);
  const auto& b = *lo;
  const double t = (device_arc_mm - a.device_arc_mm) / (b.device_arc_mm - a.device_arc_mm);
  return a.section_arc_mm + t * (b.section_arc_mm - a.section_arc_mm);
}

}  // namespace evar::deform
