// `evarnode segment`: the device in one fluoroscopy frame.
#include <chrono>
#include <opencv2/imgcodecs.hpp>

#include "commands.hpp"
#include "evar/geometry/device_segmentation.hpp"
#include "evar/geometry/image_file.hpp"
#include "evar/base/input_error.hpp"
#include "evar/node/logging.hpp"
#include "fluoro_input.hpp"
#include "json_file.hpp"
#include "segmentation_setup.hpp"

namespace evar::app {

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
  if (!cmd.overlay.empty()) geometry::write_image_file(cmd.overlay, device_overlay(in.image, found.points, found.found));
  if (!found.found) {
    node::log().warn("{}: no device found: {}", cmd.image.string(), found.reason);
    return 3;
  }
  node::log().info("{}: device of {:.0f} px, confidence {:.2f}, {}reaching the field border, {:.1f} ms; wrote {}",
             cmd.image.string(), found.length_px, found.confidence, found.reaches_border ? "" : "not ", ms,
             cmd.out.string());
  return 0;
}

}  // namespace evar::app
