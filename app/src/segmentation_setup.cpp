#include "segmentation_setup.hpp"

#include "evar/geometry/carm_projection.hpp"
#include "evar/base/input_error.hpp"

namespace evar::app {

geometry::SegmentationOptions segmentation_options(const SegmentParams& p, const FluoroInput& in) {
  geometry::SegmentationOptions o;
  if (p.width_px) o.device_width_px = *p.width_px;
  else if (in.view) o.device_width_px = geometry::device_shadow_width_px(*in.view, p.diameter_mm);
  if (!(o.device_width_px > 0.5 && o.device_width_px < 100.0))
    throw base::InputError("the device's shadow would be " + std::to_string(o.device_width_px) +
                               " px wide with this geometry and --device-diameter-mm; 0.5 to 100 px can be searched "
                               "(check the pixel spacing, or give --width-px)");
  if (p.seed.size() == 2) o.seed_px = Eigen::Vector2d(p.seed[0], p.seed[1]);
  o.min_contrast = p.min_contrast;
  o.field_mask = in.field_mask;
  o.hidden_mask = in.hidden_mask;
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

}  // namespace evar::app
