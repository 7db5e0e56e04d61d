#include "evar/node/node_options.hpp"

#include <algorithm>

#include <Eigen/LU>
#include <cmath>
#include <stdexcept>
#include <string>

#include "evar/acquisition/frame_loss_monitor.hpp"
#include "evar/node/view_pair_selector.hpp"

namespace evar::node {

namespace {

[[noreturn]] void bad(const std::string& field, const std::string& what) {
  throw std::invalid_argument("node options: " + field + ": " + what);
}

void positive(const std::string& field, std::chrono::milliseconds d) {
  if (d.count() <= 0) bad(field, std::to_string(d.count()) + " ms; must be more than 0 ms");
}

void positive(const std::string& field, double v, const char* unit) {
  if (!(v > 0.0) || !std::isfinite(v)) bad(field, std::to_string(v) + " " + unit + "; must be a positive number");
}

void share(const std::string& field, double v) {
  if (!(v >= 0.0 && v <= 1.0)) bad(field, std::to_string(v) + "; must be a share from 0 to 1");
}

}  // namespace

void check_options(const NodeOptions& o) {
  const auto& d = o.detector;
  if (d.cols <= 0 || d.rows <= 0)
    bad("detector", std::to_string(d.cols) + " x " + std::to_string(d.rows) + " pixels; the detector needs a size");
  positive("detector.row_spacing_mm", d.row_spacing_mm, "mm");
  positive("detector.col_spacing_mm", d.col_spacing_mm, "mm");
  if (o.video_mapping && o.zoom_modes.empty())
    if (const auto problem = geometry::video_mapping_fit_problem(*o.video_mapping, d.cols, d.rows); !problem.empty())
      bad("video_mapping", problem);
  // With zoom modes the detector is the physical one; each mode's image is shown through the
  // display's mapping turned and flipped as the mode turns and flips it.
  std::vector<int> numbers;
  for (std::size_t k = 0; k < o.zoom_modes.size(); ++k) {
    const geometry::ZoomMode& z = o.zoom_modes[k];
    const std::string at = "zoom_modes[" + std::to_string(k) + "]";
    if (const auto problem = geometry::zoom_mode_problem(z, d); !problem.empty()) bad(at, problem);
    if (std::find(numbers.begin(), numbers.end(), z.number) != numbers.end())
      bad(at + ".mode", std::to_string(z.number) + " is given twice");
    numbers.push_back(z.number);
    if (const auto mapping = geometry::frame_mapping(o.video_mapping, z))
      if (const auto problem = geometry::video_mapping_fit_problem(*mapping, z.cols, z.rows); !problem.empty())
        bad(o.video_mapping ? "video_mapping" : at, "in zoom mode " + std::to_string(z.number) + " \"" + z.name + "\": " + problem);
  }
  if (o.zoom_mode != 0 && std::find(numbers.begin(), numbers.end(), o.zoom_mode) == numbers.end())
    bad("zoom_mode", std::to_string(o.zoom_mode) + " is not one of zoom_modes; fix a mode node.json lists");

  if (!o.registration.allFinite()) bad("registration", "not finite");
  if ((o.registration.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9)
    bad("registration", "the last row must be 0 0 0 1 (an affine CT to C-arm transform)");
  if (!(o.registration.topLeftCorner<3, 3>().determinant() > 0.0))
    bad("registration", "the 3 x 3 part is singular or mirrors space; a registration never does");

  positive("candidate.device_diameter_mm", o.candidate.device_diameter_mm, "mm");
  if (!(o.candidate.min_contrast >= 0.0)) bad("candidate.min_contrast", "must be 0 or more");
  share("candidate.min_confidence", o.candidate.min_confidence);

  positive("adaptation.max_mean_residual_px", o.adaptation.max_mean_residual_px, "px");
  positive("adaptation.min_length_mm", o.adaptation.min_length_mm, "mm");
  if (!(o.adaptation.reading_margin_mm >= 0.0)) bad("adaptation.reading_margin_mm", "must be 0 mm or more");
  positive("adaptation.outside_limit_mm", o.adaptation.outside_limit_mm, "mm");
  share("adaptation.max_share_outside", o.adaptation.max_share_outside);
  if (!(o.adaptation.orientation_outside_mm >= o.adaptation.reading_margin_mm) ||
      !std::isfinite(o.adaptation.orientation_outside_mm))
    bad("adaptation.orientation_outside_mm", "must be finite and no less than adaptation.reading_margin_mm");

  positive("timeline.window", o.timeline.window);
  positive("timeline.stale_after", o.timeline.stale_after);
  positive("timeline.restart_after", o.timeline.restart_after);
  positive("timeline.ahead_after", o.timeline.ahead_after);
  if (!(o.timeline.settled_tolerance_deg >= 0.0)) bad("timeline.settled_tolerance_deg", "must be 0 degrees or more");
  if (!(o.timeline.settled_tolerance_mm >= 0.0)) bad("timeline.settled_tolerance_mm", "must be 0 mm or more");

  if (o.compositor.supersample < 1 || o.compositor.supersample > 8)
    bad("compositor.supersample", std::to_string(o.compositor.supersample) + "; must be 1 to 8");
  if (!(o.compositor.window_level.window >= 0.0)) bad("compositor.window_level.window", "must be 0 or more");

  positive("video_stall", o.video_stall);
  positive("held_frame_interval", o.held_frame_interval);
  positive("alert_hold", o.alert_hold);
  positive("video_mapping_check", o.video_mapping_check);
  positive("carm_notice_hold", o.carm_notice_hold);
  if (o.input_queue == 0) bad("input_queue", "0 frames; a queue holds at least 1");
  if (o.output_queue == 0) bad("output_queue", "0 frames; a queue holds at least 1");

  // The parts that check their own options say what is wrong in their own words.
  try {
    (void)ViewPairSelector(o.adaptation.reconstruction.min_separation_deg, o.pairs);
    (void)acquisition::FrameLossMonitor(o.frame_loss);
    check_options(o.pelvis);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("node options: ") + e.what());
  }
}

}  // namespace evar::node
