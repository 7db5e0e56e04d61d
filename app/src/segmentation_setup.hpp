#pragma once
// What `segment` and `reconstruct` share: the segmentation options from the command line
// and a frame's geometry, and the JSON record of a segmentation.
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "evar/geometry/device_segmentation.hpp"
#include "fluoro_input.hpp"

namespace evar::app {

/// The shadow width comes from --width-px, else from the geometry and the diameter.
/// InputError when it is outside what can be searched.
geometry::SegmentationOptions segmentation_options(const SegmentParams& p, const FluoroInput& in);

nlohmann::json segmentation_json(const geometry::DeviceCurve2D& d, const geometry::SegmentationOptions& o);

}  // namespace evar::app
