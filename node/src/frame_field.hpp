#pragma once
// What the frames of one zoom mode are to the node (issue 31): the pixels the projection
// lands on (the mode's image, or the detector itself without zoom modes), how the frames
// hold them (the display's mapping composed with the mode's turn and flip), the frames'
// size, and where in the field a device may be looked for. The node makes one per zoom
// mode at start and picks a frame's by the mode the C-arm link says.
#include <optional>
#include <string>
#include <vector>

#include "evar/geometry/detector.hpp"
#include "evar/geometry/video_mapping.hpp"
#include "evar/geometry/zoom_mode.hpp"
#include "evar/node/device_candidate.hpp"
#include "evar/node/frame_view.hpp"
#include "evar/node/node_options.hpp"

namespace evar::node {

struct FrameField {
  const geometry::ZoomMode* zoom = nullptr;        ///< null: no zoom modes, the detector's pixels
  geometry::DetectorSpec image;                    ///< the pixels the projection lands on
  std::optional<geometry::VideoMapping> mapping;   ///< set: the frames hold them through it
  std::optional<geometry::VideoToDetector> video;  ///< the mapping on `image`
  CandidateOptions candidate;                      ///< the node's, with the field's masks
  int frame_cols = 0, frame_rows = 0;              ///< the frames' size

  /// The view of a C-arm state in this field, with the registration moved by the table.
  FrameView view(const geometry::DetectorSpec& detector, const Eigen::Matrix4d& registration,
                 const acquisition::CArmState& state) const;
  /// "zoom 32 cm" or "" without zoom modes.
  std::string label() const;
};

/// One field per zoom mode of `options` (in their order), or the detector's alone. The
/// options are checked (check_options) before.
std::vector<FrameField> frame_fields(const NodeOptions& options);

/// The field of frames the C-arm link says were taken in `zoom_mode` (0: not said), or null
/// with the reason in `why`: a mode node.json does not list, or several modes and none said
/// nor fixed. node.json's fixed mode wins over the link's.
const FrameField* field_of(const std::vector<FrameField>& fields, const NodeOptions& options, int zoom_mode, std::string& why);

}  // namespace evar::node
