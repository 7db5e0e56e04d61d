// `evarnode segment`: the device in one fluoroscopy frame.
#include <chrono>
#include <opencv2/imgcodecs.hpp>

#include "commands.hpp"
#include "evar/geometry/device_segmentation.hpp"
#include "evar/geometry/input_error.hpp"
#include "fluoro_input.hpp"
#include "json_file.hpp"
#include "logging.hpp"

namespace evar::app {

geometry::SegmentationOptions segmentation_options(const SegmentParams& p, const FluoroInput& in) {
  geometry::SegmentationOptions o;
  if (p.width_px) o.device_width_px = *p.width_px;
  else if (in.view) o.device_width_px = device_width_px(*in.view, p.diameter_mm);
  if (!(o.device_width_px > 0.5 && o.device_width_px < 100.0))
    throw geometry::InputError("the device's shadow would be " + std::to_string(o.device_width_px) +
                               " px wide with this geometry and --device-diameter-mm; 0.5 to 100 px can be searched "
                               "(check the pixel spacing, or give --width-px)");
  if (p.seed.size() == 2) o.seed_px = Eigen::Vector2d(p.seed[0], p.seed[1]);
  o.min_contrast = p.min_contrast;
  return o;
}

nlohmann::json segmentation_json(const geometry::DeviceCurve2D& d, const geometry::SegmentationOptions& o) {
  nlohmann::json points = nlohmann::json::array();
  for (const auto& p : d.points) points.push_back({p.x(), p.y()});
  return {{"found", d.found},
          {"reason", d.reason},
          {"points_px", points},
          {"confidence", d.confidence},
          {"length_px", d.length_px},
          {"gap_fraction", d.gap_fraction},
          {"median_response", d.median_response},
          {"contrast", d.contrast},
          {"side_step", d.side_step},
          {"reaches_border", d.reaches_border},
          {"field_px", {d.field.x, d.field.y, d.field.width, d.field.height}},
          {"device_width_px", o.device_width_px}};
}

int run_segment(const SegmentCommand& cmd) {
  const FluoroInput in = load_fluoro(cmd.image, cmd.geometry);
  const auto options = segmentation_options(cmd.params, in);
  const auto t0 = std::chrono::steady_clock::now();
  const auto found = geometry::segment_device(in.image, options);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  auto j = segmentation_json(found, options);
  j["format"] = "evarnode-device-2d";
  j["version"] = 1;
  j["image"] = cmd.image.string();
  j["image_size_px"] = {in.image.cols, in.image.rows};
  j["segment_ms"] = ms;
  write_json(cmd.out, j);
  if (!cmd.overlay.empty() && !cv::imwrite(cmd.overlay.string(), device_overlay(in.image, found.points, found.found)))
    throw std::runtime_error(cmd.overlay.string() + ": cannot write the overlay picture");
  if (!found.found) {
    log().warn("{}: no device found: {}", cmd.image.string(), found.reason);
    return 3;
  }
  log().info("{}: device of {:.0f} px, confidence {:.2f}, {}reaching the field border, {:.1f} ms; wrote {}",
             cmd.image.string(), found.length_px, found.confidence, found.reaches_border ? "" : "not ", ms,
             cmd.out.string());
  return 0;
}

}  // namespace evar::app
