#include "frame_field.hpp"

#include "evar/geometry/video_area.hpp"
#include "evar/geometry/video_frame.hpp"

namespace evar::node {

FrameView FrameField::view(const geometry::DetectorSpec& detector, const Eigen::Matrix4d& registration,
                           const acquisition::CArmState& state) const {
  if (!zoom) return frame_view(detector, registration, state);
  return frame_view(geometry::zoom_view(detector, *zoom, state.primary_deg, state.secondary_deg, state.sid_mm, state.sod_mm),
                    registration, state);
}

std::string FrameField::label() const { return zoom ? "zoom " + zoom->name : std::string(); }

std::vector<FrameField> frame_fields(const NodeOptions& options) {
  const auto make = [&](const geometry::ZoomMode* zoom) {
    FrameField f;
    f.zoom = zoom;
    f.image = zoom ? geometry::image_detector(*zoom) : options.detector;
    f.mapping = zoom ? geometry::frame_mapping(options.video_mapping, *zoom) : options.video_mapping;
    f.candidate = options.candidate;
    f.frame_cols = f.image.cols;
    f.frame_rows = f.image.rows;
    if (f.mapping) {
      // The device is searched for only where the frames show the field.
      f.video.emplace(*f.mapping, f.image.cols, f.image.rows);
      f.candidate.field_mask = geometry::detector_field_mask(*f.mapping, *f.video);
      f.candidate.hidden_mask = geometry::detector_text_mask(*f.mapping, *f.video);
      f.frame_cols = f.mapping->video_cols;
      f.frame_rows = f.mapping->video_rows;
    }
    return f;
  };
  std::vector<FrameField> fields;
  if (options.zoom_modes.empty()) fields.push_back(make(nullptr));
  for (const geometry::ZoomMode& z : options.zoom_modes) fields.push_back(make(&z));
  return fields;
}

const FrameField* field_of(const std::vector<FrameField>& fields, const NodeOptions& options, int zoom_mode, std::string& why) {
  if (fields.size() == 1 && !fields.front().zoom) return &fields.front();
  const int wanted = options.zoom_mode != 0 ? options.zoom_mode : zoom_mode;
  if (wanted == 0) {
    if (fields.size() == 1) return &fields.front();  // one mode: the link has nothing to choose
    why = "the C-arm link does not say the zoom mode (link protocol 1, or no zoom readout) and node.json lists " +
          std::to_string(fields.size()) + "; fix one with node.json \"zoom_mode\"";
    return nullptr;
  }
  for (const FrameField& f : fields)
    if (f.zoom->number == wanted) return &f;
  std::string listed;  // only for the refusal: this runs for every frame
  for (const FrameField& f : fields)
    listed += (listed.empty() ? "" : ", ") + std::to_string(f.zoom->number) + " \"" + f.zoom->name + "\"";
  why = "zoom mode " + std::to_string(wanted) + " from the C-arm link is not one of node.json's zoom_modes (" + listed +
        "); add it";
  return nullptr;
}

}  // namespace evar::node
