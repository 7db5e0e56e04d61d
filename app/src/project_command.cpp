// `evarnode project`: pixel coordinates of points in a C-arm view, for checking the
// projection conventions by hand (docs/CARM_GEOMETRY.md).
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "evar/geometry/carm_projection.hpp"
#include "evar/base/input_error.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/node/logging.hpp"
#include "json_file.hpp"
#include "view_input.hpp"

namespace evar::app {

namespace {
std::string describe(const geometry::CArmView& v) {
  if (v.projection_matrix) return "calibrated projection matrix";
  const double a = v.primary_angle_deg, b = v.secondary_angle_deg;
  return fmt::format("{} {:.1f} / {} {:.1f}, SID {:.0f} mm, SOD {:.0f} mm", a >= 0 ? "LAO" : "RAO", std::abs(a),
                     b >= 0 ? "CRA" : "CAU", std::abs(b), v.source_to_detector_mm, v.source_to_isocenter_mm);
}
}  // namespace

int run_project(const ProjectCommand& cmd) {
  const geometry::ViewGeometryFile file = read_view_file(cmd.geometry);
  const geometry::CArmView& view = file.view;
  geometry::ProjectionMatrix P = geometry::projection_matrix(view);
  if (!cmd.registration.empty()) P = geometry::registered(P, geometry::read_registration(cmd.registration));
  std::optional<geometry::VideoToDetector> video;
  if (file.video_mapping) video.emplace(*file.video_mapping, view.detector_cols, view.detector_rows);
  std::vector<geometry::ControlPoint> points;
  for (const auto& m : geometry::read_markups(cmd.points))
    points.insert(points.end(), m.points.begin(), m.points.end());
  if (points.empty()) throw base::InputError(cmd.points.string() + ": the file has no control points");

  std::printf("# %s: %s, detector %d x %d px (%.3f x %.3f mm)\n", cmd.geometry.string().c_str(), describe(view).c_str(),
              view.detector_cols, view.detector_rows, view.col_spacing_mm, view.row_spacing_mm);
  std::printf("# %s coordinates; pixel (0,0) = centre of the top-left pixel, u to the right, v down\n",
              cmd.registration.empty() ? "C-arm (LPS, isocenter at 0)" : "CT LPS, through the registration");
  std::printf("%-24s %10s %10s %10s %10s %10s %11s  %s\n", "label", "L (mm)", "P (mm)", "S (mm)", "u (px)", "v (px)",
              "depth (mm)", "where");
  nlohmann::json out = nlohmann::json::array();
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto& p = points[i];
    const std::string label = p.label.empty() ? "#" + std::to_string(i) : p.label;
    const auto px = geometry::project(P, p.position_lps);
    const double depth = geometry::depth_mm(P, p.position_lps);
    std::string where = "behind the source";
    if (px) {
      const bool inside = px->x() >= -0.5 && px->y() >= -0.5 && px->x() <= view.detector_cols - 0.5 &&
                          px->y() <= view.detector_rows - 0.5;
      where = inside ? "on the detector" : "outside the detector";
    }
    const auto& x = p.position_lps;
    if (px)
      std::printf("%-24s %10.2f %10.2f %10.2f %10.2f %10.2f %11.1f  %s\n", label.c_str(), x.x(), x.y(), x.z(), px->x(),
                  px->y(), depth, where.c_str());
    else
      std::printf("%-24s %10.2f %10.2f %10.2f %10s %10s %11.1f  %s\n", label.c_str(), x.x(), x.y(), x.z(), "-", "-",
                  depth, where.c_str());
    nlohmann::json j{{"label", label}, {"position_mm", {x.x(), x.y(), x.z()}}, {"depth_mm", depth}, {"where", where}};
    j["pixel"] = px ? nlohmann::json{px->x(), px->y()} : nlohmann::json(nullptr);
    if (video) {
      const auto shown = px ? std::optional(video->to_video(*px)) : std::nullopt;
      j["video_pixel"] = shown ? nlohmann::json{shown->x(), shown->y()} : nlohmann::json(nullptr);
      if (shown) std::printf("%-24s %10s %10s %10s %10.2f %10.2f %11s  in the video frame\n", "", "", "", "", shown->x(), shown->y(), "");
    }
    out.push_back(j);
  }
  if (!cmd.out.empty()) {
    write_json(cmd.out, {{"geometry", cmd.geometry.string()}, {"points", out}});
    node::log().info("wrote {}", cmd.out.string());
  }
  return 0;
}

}  // namespace evar::app
