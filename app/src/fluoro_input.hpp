#pragma once
// One fluoroscopy frame from the command line: a PNG/TIFF image (with an optional view
// geometry JSON) or a DICOM XA / Enhanced XA file (which carries its own geometry).
#include <filesystem>
#include <optional>

#include <opencv2/core.hpp>

#include "evar/geometry/carm_projection.hpp"

namespace evar::app {

struct FluoroInput {
  cv::Mat image;                               ///< CV_8UC1 or CV_16UC1, dark = attenuating; the detector's
                                               ///< pixels (a video-out frame is mapped back, view's video_mapping)
  std::optional<geometry::CArmView> view;      ///< from --geometry or the DICOM header
  cv::Mat field_mask;                          ///< where a video-out frame shows the field; empty: everywhere
  cv::Mat hidden_mask;                         ///< where its burned-in text covers the field; empty: nowhere
};

/// InputError naming the file when it cannot be read, is empty, or is not grey-level.
FluoroInput load_fluoro(const std::filesystem::path& image, const std::filesystem::path& geometry = {});

/// The frame with the device drawn over it (tip marked), for --overlay pictures.
cv::Mat device_overlay(const cv::Mat& image, const std::vector<Eigen::Vector2d>& points, bool found);

}  // namespace evar::app
