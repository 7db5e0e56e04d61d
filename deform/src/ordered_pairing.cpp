#include "evar/deform/ordered_pairing.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace evar::deform {
namespace {

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

}  // namespace

std::vector<SectionPartner> ordered_pairing(const geometry::Polyline& centerline, const geometry::Polyline& device,
                                            double step_mm) {
  if (!(step_mm > 0.0)) throw std::invalid_argument("ordered pairing: the step must be > 0");
  if (centerline.size() < 2 || device.size() < 2) return {};
  const auto centerline_arc = geometry::arc_lengths(centerline);
  const auto device_arc = geometry::arc_lengths(device);
  const double device_length = device_arc.back();
  if (!(device_length > 0.0)) return {};
  const geometry::PolylineProjector onto_centerline(centerline);
  int segment = -1;
  const double first = onto_centerline.project(device.front(), segment, &segment).arc_length_mm;
  const double last = onto_centerline.project(device.back(), segment, &segment).arc_length_mm;
  // Sections evenly spaced from the first foot to the last, at most step_mm apart (the
  // same sections whichever end the device is given from).
  const int count = static_cast<int>(std::ceil(std::abs(last - first) / step_mm - 1e-9)) + 1;
  if (count < 5) return {};
  const double h = (last - first) / (count - 1);  // signed
  const bool proximal_first = h >= 0.0;           // the device's first sample is the proximal end

  std::vector<SectionPartner> pairs(static_cast<std::size_t>(count));
  std::vector<double> shortest(static_cast<std::size_t>(count));
  const geometry::PolylineProjector onto_device(device);
  int device_segment = -1;
  for (int k = 0; k < count; ++k) {
    const double s = first + k * h;
    pairs[static_cast<std::size_t>(k)].section_arc_mm = s;
    shortest[static_cast<std::size_t>(k)] =
        onto_device.project(geometry::point_at(centerline, centerline_arc, s), device_segment, &device_segment).arc_length_mm;
  }
  make_non_decreasing(shortest);
  // Sliding keeps the arc from the proximal section (the centerline's start side).
  for (int k = 0; k < count; ++k) {
    const double from_proximal = std::abs(h) * (proximal_first ? k : count - 1 - k);
    const double sliding = proximal_first ? std::min(device_length, from_proximal)
                                          : std::max(0.0, device_length - from_proximal);
    pairs[static_cast<std::size_t>(k)].device_arc_mm = 0.5 * (shortest[static_cast<std::size_t>(k)] + sliding);
  }
  return pairs;
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
