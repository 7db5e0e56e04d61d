// Accuracy of segmentation and two-view reconstruction on rendered frames of a known wire
// (sim::render_fluoro, 1024 x 1024 detector of 0.3 mm pixels, SID 1200, SOD 800), as view
// separation and dose vary. Prints the Markdown tables of docs/ACCURACY.md and a JSON
// record (--json FILE). Run: build/bench/evar_accuracy [--seeds N] [--json FILE]
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "evar/base/atomic_file.hpp"
#include "evar/geometry/device_segmentation.hpp"
#include "evar/geometry/two_view_reconstruction.hpp"
#include "evar/sim/curve_metrics.hpp"
#include "evar/sim/fluoro_render.hpp"

using namespace evar;

namespace {

geometry::CArmView view(double primary, double secondary) {
  geometry::CArmView v;
  v.primary_angle_deg = primary;
  v.secondary_angle_deg = secondary;
  v.source_to_detector_mm = 1200;
  v.source_to_isocenter_mm = 800;
  v.detector_cols = v.detector_rows = 1024;
  v.row_spacing_mm = v.col_spacing_mm = 0.3;
  return v;
}

struct Row {
  double separation = 0, photons = 0;
  int runs = 0, segmented = 0, reconstructed = 0;
  double seg_distance_px = 0, seg_coverage = 0, mean_mm = 0, max_mm = 0, residual_px = 0;
  std::string failure;
};

Row study(double separation, double photons, int seeds) {
  Row row;
  row.separation = separation;
  row.photons = photons;
  const auto truth = sim::iliac_guidewire();
  for (int seed = 1; seed <= seeds; ++seed) {
    ++row.runs;
    const auto v1 = view(separation / 2, 5), v2 = view(-separation / 2, -5);
    const auto P1 = geometry::projection_matrix(v1), P2 = geometry::projection_matrix(v2);
    sim::FluoroOptions o;
    o.photons_per_pixel = photons;
    o.seed = static_cast<std::uint64_t>(seed);
    const auto f1 = sim::render_fluoro(P1, v1, {truth}, o);
    o.seed += 1000;
    const auto f2 = sim::render_fluoro(P2, v2, {truth}, o);
    geometry::SegmentationOptions so;
    so.device_width_px = geometry::device_shadow_width_px(v1, 0.89);
    const auto s1 = geometry::segment_device(f1.image, so), s2 = geometry::segment_device(f2.image, so);
    if (!s1.found || !s2.found) {
      row.failure = s1.found ? s2.reason : s1.reason;
      continue;
    }
    ++row.segmented;
    const double rim = 3.0 * so.device_width_px;
    for (const auto* pr : {&s1, &s2}) {
      const cv::Rect2d region(pr->field.x + rim, pr->field.y + rim, pr->field.width - 2 * rim, pr->field.height - 2 * rim);
      const auto m = sim::match_curve(pr->points, (pr == &s1 ? f1 : f2).truth.front(), region);
      row.seg_distance_px += m.mean_distance_px / 2;
      row.seg_coverage += m.coverage / 2;
    }
    try {
      const auto r = geometry::reconstruct_two_view(s1.points, P1, s2.points, P2);
      double sum = 0, worst = 0;
      for (const auto& p : r.points) {
        const double d = geometry::project_onto(truth, p).distance_mm;
        sum += d;
        worst = std::max(worst, d);
      }
      row.mean_mm += sum / static_cast<double>(r.points.size());
      row.max_mm = std::max(row.max_mm, worst);
      row.residual_px += r.mean_residual_px;
      ++row.reconstructed;
    } catch (const geometry::ReconstructionError& e) {
      row.failure = e.what();
    }
  }
  if (row.segmented) row.seg_distance_px /= row.segmented, row.seg_coverage /= row.segmented;
  if (row.reconstructed) row.mean_mm /= row.reconstructed, row.residual_px /= row.reconstructed;
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  int seeds = 3;
  std::string json_path;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--seeds") seeds = std::atoi(argv[i + 1]);
    else if (a == "--json") json_path = argv[i + 1];
  }
  nlohmann::json record = nlohmann::json::array();
  const auto table = [&](const char* title, const std::vector<std::pair<double, double>>& cases) {
    std::printf("\n%s\n\n| separation (deg) | quanta per pixel | segmented | reconstructed | segmentation: mean distance (px), coverage | reconstruction: mean error (mm) | worst point (mm) | reprojection residual (px) |\n| --- | --- | --- | --- | --- | --- | --- | --- |\n", title);
    for (const auto& [sep, photons] : cases) {
      const Row r = study(sep, photons, seeds);
      std::printf("| %.0f | %.0f | %d/%d | %d/%d | %.2f, %.1f %% | %.3f | %.2f | %.2f |\n", sep, photons, r.segmented, r.runs,
                  r.reconstructed, r.runs, r.seg_distance_px, 100 * r.seg_coverage, r.mean_mm, r.max_mm, r.residual_px);
      if (!r.failure.empty()) std::printf("\n  (a failure: %s)\n\n", r.failure.c_str());
      std::fflush(stdout);
      record.push_back({{"separation_deg", sep}, {"photons_per_pixel", photons}, {"runs", r.runs}, {"segmented", r.segmented},
                        {"reconstructed", r.reconstructed}, {"segmentation_mean_distance_px", r.seg_distance_px},
                        {"segmentation_coverage", r.seg_coverage}, {"mean_error_mm", r.mean_mm}, {"max_error_mm", r.max_mm},
                        {"mean_residual_px", r.residual_px}, {"failure", r.failure}});
    }
  };
  table("### View separation (default dose, 3000 quanta per unattenuated pixel)",
        {{20, 3000}, {30, 3000}, {45, 3000}, {60, 3000}, {90, 3000}, {120, 3000}});
  table("### Dose (views 60 degrees apart)", {{60, 1000}, {60, 300}, {60, 100}, {60, 30}});
  if (!json_path.empty()) evar::base::write_file_atomically(json_path, record.dump(2) + "\n");
  return 0;
}
