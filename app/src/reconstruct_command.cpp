// `evarnode reconstruct`: the device in 3D from two frames.
#include <Eigen/Geometry>
#include <chrono>
#include <opencv2/imgcodecs.hpp>

#include "commands.hpp"
#include "evar/geometry/device_segmentation.hpp"
#include "evar/geometry/image_file.hpp"
#include "evar/base/input_error.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/geometry/two_view_reconstruction.hpp"
#include "evar/node/logging.hpp"
#include "fluoro_input.hpp"
#include "json_file.hpp"
#include "segmentation_setup.hpp"

namespace evar::app {

int run_reconstruct(const ReconstructCommand& cmd) {
  if (cmd.images.size() != 2) throw base::InputError("reconstruct: give --image exactly twice");
  if (!cmd.geometries.empty() && cmd.geometries.size() != 2)
    throw base::InputError("reconstruct: give --geometry for both images (in the same order) or for none (DICOM)");
  const auto t0 = std::chrono::steady_clock::now();
  FluoroInput in[2];
  geometry::DeviceCurve2D found[2];
  geometry::SegmentationOptions options[2];
  geometry::ProjectionMatrix P[2];
  for (int k = 0; k < 2; ++k) {
    in[k] = load_fluoro(cmd.images[static_cast<std::size_t>(k)], cmd.geometries.empty() ? std::filesystem::path() : cmd.geometries[static_cast<std::size_t>(k)]);
    if (!in[k].view)
      throw base::InputError(cmd.images[static_cast<std::size_t>(k)].string() +
                                 ": no view geometry (give --geometry, or a DICOM XA file)");
    P[k] = geometry::projection_matrix(*in[k].view);
    options[k] = segmentation_options(cmd.params, in[k]);
    options[k].seed_px.reset();  // one seed cannot hold for two views
    found[k] = geometry::segment_device(in[k].image, options[k]);
  }
  const double segment_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  nlohmann::json report{{"format", "evarnode-reconstruction-report"},
                        {"version", 1},
                        {"views", nlohmann::json::array()},
                        {"segment_ms", segment_ms}};
  for (int k = 0; k < 2; ++k) {
    auto v = segmentation_json(found[k], options[k]);
    v["image"] = cmd.images[static_cast<std::size_t>(k)].string();
    report["views"].push_back(v);
    if (!cmd.overlay_prefix.empty()) {
      const auto path = cmd.overlay_prefix.string() + std::to_string(k + 1) + ".png";
      geometry::write_image_file(path, device_overlay(in[k].image, found[k].points, found[k].found));
    }
  }
  const auto write_report = [&] {
    if (!cmd.report.empty()) write_json(cmd.report, report);
  };
  for (int k = 0; k < 2; ++k)
    if (!found[k].found) {
      report["error"] = "no device in view " + std::to_string(k + 1) + ": " + found[k].reason;
      write_report();
      throw base::InputError(cmd.images[static_cast<std::size_t>(k)].string() + ": no device found: " + found[k].reason);
    }
  geometry::ReconstructionOptions ro;
  ro.min_separation_deg = cmd.min_separation_deg;
  geometry::Reconstruction r;
  const auto t1 = std::chrono::steady_clock::now();
  try {
    r = geometry::reconstruct_two_view(found[0].points, P[0], found[1].points, P[1], ro);
  } catch (const geometry::ReconstructionError& e) {
    report["error"] = e.what();
    write_report();
    throw base::InputError(std::string("reconstruct: ") + e.what());
  }
  const double reconstruct_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t1).count();

  // Into CT LPS when a registration maps CT into the C-arm frame.
  geometry::Polyline points = r.points;
  if (!cmd.registration.empty()) {
    const Eigen::Matrix4d T_inv = geometry::read_registration(cmd.registration).inverse();
    for (auto& p : points) p = (T_inv * p.homogeneous()).head<3>();
  }
  geometry::Markup curve{"Curve", "device", {}};
  for (std::size_t i = 0; i < points.size(); ++i)
    curve.points.push_back({i == 0 ? "tip" : "", points[i]});
  geometry::write_markups(cmd.out, {curve});

  report["reconstruct_ms"] = reconstruct_ms;
  report["separation_deg"] = r.separation_deg;
  report["points"] = points.size();
  report["mean_residual_px"] = r.mean_residual_px;
  report["max_residual_px"] = r.max_residual_px;
  report["reliable_fraction"] = r.reliable_fraction;
  report["matched_fraction"] = {r.matched_fraction_1, r.matched_fraction_2};
  report["kept_fraction"] = r.kept_fraction;
  report["residual_px"] = r.residual_px;
  report["reliable"] = r.reliable;
  report["coordinate_system"] = cmd.registration.empty() ? "C-arm LPS (isocenter at the origin)" : "CT LPS";
  report["output"] = cmd.out.string();
  write_report();
  node::log().info("device in 3D: {} points over {:.0f} mm, views {:.1f} degrees apart, reprojection residual mean {:.2f} px "
             "(max {:.2f}), {:.0f} % reliable, {:.0f} % of the matched curve kept; {:.1f} ms segmentation + {:.1f} ms reconstruction; wrote {}",
             points.size(), geometry::arc_lengths(points).back(), r.separation_deg, r.mean_residual_px, r.max_residual_px,
             100.0 * r.reliable_fraction, 100.0 * r.kept_fraction, segment_ms, reconstruct_ms, cmd.out.string());
  return 0;
}

}  // namespace evar::app
