#include "evar/node/model_adaptation.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <limits>
#include <numeric>

#include "evar/base/elapsed.hpp"
#include "evar/base/input_error.hpp"

namespace evar::node {

using base::ms_since;

overlay::RoadmapModel roadmap_model(const geometry::Scene& scene, const AdaptedModel* adapted) {
  overlay::RoadmapModel r;
  for (const auto& v : scene.vessels) r.initial.push_back(v.mesh.mesh);
  r.initial_landmarks = scene.landmarks;
  if (adapted != nullptr) show_adapted(r, *adapted);
  return r;
}

void show_adapted(overlay::RoadmapModel& roadmap, const AdaptedModel& adapted) {
  roadmap.adapted.clear();
  for (const auto& v : adapted.deformation.vessels) roadmap.adapted.push_back(v.mesh);
  roadmap.adapted_landmarks = adapted.deformation.landmarks;
  roadmap.device = adapted.reconstruction.points;
}

std::vector<double> outside_lumen_mm(const geometry::Polyline& device, const deform::SceneDeformer& deformer) {
  const auto& vessels = deformer.scene().vessels;
  std::vector<double> out;
  for (const auto& p : device) {
    double outside = std::numeric_limits<double>::infinity();
    for (std::size_t v = 0; v < vessels.size(); ++v) {
      const auto q = geometry::project_onto(vessels[v].centerline, p);
      // Past a centerline's end (a wire running on above an infrarenal segmentation) the
      // vessel goes on unmodelled: only the distance across its axis there counts.
      const Eigen::Vector3d off = p - q.point;
      const double across_mm =
          q.beyond_start || q.beyond_end ? (off - off.dot(q.tangent) * q.tangent).norm() : q.distance_mm;
      outside = std::min(outside, std::max(0.0, across_mm - deformer.lumen_radius_mm(v, q.arc_length_mm)));
    }
    out.push_back(outside);
  }
  return out;
}

double mean_outside_lumen_mm(const geometry::Polyline& device, const deform::SceneDeformer& deformer) {
  const auto outside = outside_lumen_mm(device, deformer);
  if (outside.empty()) return std::numeric_limits<double>::infinity();
  return std::accumulate(outside.begin(), outside.end(), 0.0) / static_cast<double>(outside.size());
}

void check_in_the_vessels(const geometry::Polyline& device, const deform::SceneDeformer& deformer,
                          const AdaptationOptions& o) {
  const auto outside = outside_lumen_mm(device, deformer);
  const auto far = std::count_if(outside.begin(), outside.end(), [&](double d) { return d > o.outside_limit_mm; });
  const double share = outside.empty() ? 0.0 : static_cast<double>(far) / static_cast<double>(outside.size());
  if (share <= o.max_share_outside) return;
  char why[256];
  std::snprintf(why, sizeof why,
                "reconstruction refused: %.0f %% of the device runs more than %.0f mm outside the preoperative vessels "
                "(another structure segmented, e.g. an ECG lead or a second wire, or a wrong registration?)",
                100.0 * share, o.outside_limit_mm);
  throw AdaptationError(why);
}

std::size_t reading_in_the_vessels(const std::vector<geometry::Reconstruction>& readings,
                                   const deform::SceneDeformer& deformer, double margin_mm) {
  if (readings.empty()) throw std::invalid_argument("reading_in_the_vessels: no reading");
  std::vector<double> outside_mm;
  for (const auto& r : readings) outside_mm.push_back(mean_outside_lumen_mm(r.points, deformer));
  std::vector<std::size_t> order(readings.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return outside_mm[a] < outside_mm[b]; });
  if (readings.size() == 1 || outside_mm[order[1]] - outside_mm[order[0]] >= margin_mm) return order[0];
  char why[256];
  std::snprintf(why, sizeof why,
                "the device reads two ways in these views and both lie in the vessels or near them (%.1f and %.1f mm "
                "outside their lumen on average): take views turned about another axis",
                outside_mm[order[0]], outside_mm[order[1]]);
  throw AdaptationError(why);
}

AdaptedModel adapt_model(const deform::SceneDeformer& deformer, const ViewPair& pair, const AdaptationOptions& options,
                         const deform::SceneDeformation* previous) {
  AdaptedModel m;
  m.frame_earlier = pair.earlier.frame;
  m.frame_later = pair.later.frame;
  auto t0 = std::chrono::steady_clock::now();
  try {
    auto readings = geometry::reconstruct_two_view_readings(pair.earlier.curve_px, pair.earlier.geometry.P_ct,
                                                            pair.later.curve_px, pair.later.geometry.P_ct,
                                                            options.reconstruction);
    const std::size_t k =
        readings.size() == 1 ? 0 : reading_in_the_vessels(readings, deformer, options.reading_margin_mm);
    m.reconstruction = std::move(readings[k]);
  } catch (const geometry::ReconstructionError& e) {
    throw AdaptationError(std::string("reconstruction failed: ") + e.what());
  }
  m.reconstruct_ms = ms_since(t0);
  const auto& r = m.reconstruction;
  char why[160];
  if (r.mean_residual_px > options.max_mean_residual_px) {
    std::snprintf(why, sizeof why, "reconstruction refused: the device reprojects %.1f px from its curves (limit %.1f)",
                  r.mean_residual_px, options.max_mean_residual_px);
    throw AdaptationError(why);
  }
  const double length = r.points.size() < 2 ? 0.0 : geometry::arc_lengths(r.points).back();
  if (length < options.min_length_mm) {
    std::snprintf(why, sizeof why, "reconstruction refused: only %.0f mm of device seen in both views (need %.0f)",
                  length, options.min_length_mm);
    throw AdaptationError(why);
  }
  check_in_the_vessels(r.points, deformer, options);
  t0 = std::chrono::steady_clock::now();
  try {
    m.deformation = deformer.deform(r.points, previous);
  } catch (const base::InputError& e) {
    throw AdaptationError(std::string("deformation refused the device: ") + e.what());
  } catch (const std::runtime_error& e) {
    throw AdaptationError(std::string("deformation failed: ") + e.what());
  }
  m.deform_ms = ms_since(t0);
  check_finite(m);
  return m;
}

void check_finite(const AdaptedModel& m) {
  const auto& d = m.deformation;
  for (std::size_t v = 0; v < d.vessels.size(); ++v) {
    const auto& V = d.vessels[v].mesh.V;
    for (Eigen::Index i = 0; i < V.rows(); ++i)
      if (!V.row(i).allFinite())
        throw AdaptationError("deformation refused: vessel " +
                              (v < d.reports.size() ? d.reports[v].name : std::to_string(v)) + " vertex " +
                              std::to_string(i) + " is not finite");
  }
  for (const auto& l : d.landmarks)
    if (!l.position_lps.allFinite())
      throw AdaptationError("deformation refused: landmark " + l.label + " is not finite");
  for (std::size_t k = 0; k < m.reconstruction.points.size(); ++k)
    if (!m.reconstruction.points[k].allFinite())
      throw AdaptationError("reconstruction refused: device point " + std::to_string(k) + " is not finite");
}

}  // namespace evar::node
