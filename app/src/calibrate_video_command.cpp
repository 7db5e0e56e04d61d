// `evarnode calibrate-video`: the video mapping of a C-arm's video output found from a few
// grabbed frames (issue 31), written as its own file and, if asked, into node.json, with a
// picture of what was found for the operator to check.
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <optional>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "evar/base/input_error.hpp"
#include "evar/geometry/image_file.hpp"
#include "evar/geometry/json_fields.hpp"
#include "evar/geometry/video_area.hpp"
#include "evar/geometry/video_mapping.hpp"
#include "evar/node/logging.hpp"
#include "json_file.hpp"
#include "node_config.hpp"

namespace evar::app {

namespace {

std::string rect_text(const geometry::PixelRect& r) {
  return fmt::format("{:.0f} x {:.0f} at ({:.0f}, {:.0f})", r.width, r.height, r.x, r.y);
}

// The brightest of the frames, 8-bit, stretched between the black level and the 99.5th
// percentile (16-bit raw frames on a log scale, as their grey levels are quanta).
cv::Mat shown(const std::vector<cv::Mat>& frames) {
  cv::Mat brightest;
  for (const cv::Mat& f : frames) {
    cv::Mat grey = f;
    if (f.channels() != 1) cv::cvtColor(f, grey, f.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
    cv::Mat g;
    grey.convertTo(g, CV_32F);
    if (f.depth() == CV_16U) cv::log(g + 1.0f, g);
    brightest = brightest.empty() ? g : cv::max(brightest, g);
  }
  std::vector<float> v(brightest.begin<float>(), brightest.end<float>());
  std::sort(v.begin(), v.end());
  const float lo = v.front(), hi = v[v.size() * 995 / 1000];
  cv::Mat out;
  brightest.convertTo(out, CV_8U, 255.0 / std::max(hi - lo, 1e-6f), -lo * 255.0 / std::max(hi - lo, 1e-6f));
  cv::cvtColor(out, out, cv::COLOR_GRAY2BGR);
  return out;
}

// The frames with the image area (green) and the text regions (amber) outlined, and a
// legend beside them, so no label covers what it describes.
cv::Mat calibration_picture(const std::vector<cv::Mat>& frames, const geometry::VideoArea& area,
                            const geometry::VideoMapping& mapping, std::size_t frame_count) {
  const cv::Mat image = shown(frames);
  const cv::Scalar green(80, 220, 80), amber(0, 176, 255), white(235, 235, 235), dim(150, 150, 150);
  const int line = std::max(2, image.cols / 400);
  const geometry::PixelRect& r = area.image_rect;
  const cv::Rect box(static_cast<int>(r.x), static_cast<int>(r.y), static_cast<int>(r.width), static_cast<int>(r.height));
  cv::Mat picture = image.clone();
  cv::rectangle(picture, box, green, line, cv::LINE_AA);
  if (area.field_shape == geometry::FieldShape::Circle)
    cv::circle(picture, {box.x + box.width / 2, box.y + box.height / 2}, std::min(box.width, box.height) / 2, green, line,
               cv::LINE_AA);
  for (const auto& t : area.text_regions)
    cv::rectangle(picture, cv::Rect(static_cast<int>(t.x), static_cast<int>(t.y), static_cast<int>(t.width),
                                    static_cast<int>(t.height)),
                  amber, std::max(1, line / 2), cv::LINE_AA);

  const double scale = std::max(0.5, picture.rows / 900.0);
  const int step = static_cast<int>(std::lround(30 * scale)), thick = std::max(1, static_cast<int>(std::lround(scale)));
  const std::vector<std::pair<std::string, cv::Scalar>> legend{
      {"evarnode calibrate-video", white},
      {fmt::format("{} frame(s), {} x {} px", frame_count, area.video_cols, area.video_rows), dim},
      {"", white},
      {"image area (green)", green},
      {"  " + rect_text(r), white},
      {fmt::format("  {} ({:.0f} % of its rectangle)",
                   area.field_shape == geometry::FieldShape::Circle ? "circle: image intensifier" : "rectangle: flat detector",
                   100.0 * area.fill),
       white},
      {fmt::format("  turned {} deg{}", mapping.rotation_deg, mapping.mirror ? ", mirrored" : ", not mirrored"), white},
      {"  (as given: frames do not show it)", dim},
      {"", white},
      {fmt::format("burned-in text (amber): {} region(s)", area.text_regions.size()), amber},
      {"", white},
      {"Check: the green outline lies on the", dim},
      {"image's edge, and amber boxes hold", dim},
      {"only text. Correct the JSON if not.", dim}};
  int width = 0;
  for (const auto& [text, colour] : legend)
    width = std::max(width, cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, 0.6 * scale, thick, nullptr).width);
  const int panel = width + 2 * step;
  const int height = std::max(picture.rows, static_cast<int>(legend.size() + 2) * step);
  cv::Mat out(height, picture.cols + panel, CV_8UC3, cv::Scalar(30, 26, 24));
  picture.copyTo(out(cv::Rect(0, 0, picture.cols, picture.rows)));
  int y = step;
  for (const auto& [text, colour] : legend) {
    if (!text.empty())
      cv::putText(out, text, {picture.cols + step, y}, cv::FONT_HERSHEY_SIMPLEX, 0.6 * scale, colour, thick, cv::LINE_AA);
    y += step;
  }
  return out;
}

// node.json, read in its order.
nlohmann::ordered_json read_node_json(const std::filesystem::path& node_json) {
  geometry::detail::parse_json_file(node_json);  // checked as every reader of it does
  std::ifstream in(node_json);
  nlohmann::ordered_json j = nlohmann::ordered_json::parse(in);
  if (!j.is_object() || j.value("format", "") != "evarnode-node")
    throw base::InputError(node_json.string() +
                           ": format: expected \"evarnode-node\" (a node configuration to write the mapping into)");
  return j;
}

// node.json's "video_mapping" set to the mapping file's name (relative to node.json where it
// can be), so corrections to that file reach the node; every other field kept in its order.
void point_node_config_at(const std::filesystem::path& node_json, nlohmann::ordered_json j,
                          const std::filesystem::path& mapping_file) {
  std::error_code ec;
  const auto base = std::filesystem::absolute(node_json).parent_path();
  std::filesystem::path name = std::filesystem::relative(std::filesystem::absolute(mapping_file), base, ec);
  if (ec || name.empty()) name = std::filesystem::absolute(mapping_file);
  j["video_mapping"] = name.generic_string();
  write_text(node_json, j.dump(2) + "\n");
}

// Why the mapping does not fit the detector, with the turn that would make it fit; "" when it fits.
std::string misfit(const geometry::VideoMapping& mapping, int cols, int rows) {
  const std::string problem = geometry::video_mapping_fit_problem(mapping, cols, rows);
  if (problem.empty()) return "";
  geometry::VideoMapping turned = mapping;
  turned.rotation_deg = (mapping.rotation_deg + 90) % 360;
  if (geometry::video_mapping_fit_problem(turned, cols, rows).empty())
    return problem + "; the image is shown turned: give --rotation-deg " + std::to_string(turned.rotation_deg) + " or " +
           std::to_string((turned.rotation_deg + 180) % 360) + " as the display settings say";
  return problem +
         "; no turn makes it fit: the area found may include a shutter or miss a dark edge (see the picture), or "
         "the detector size is not this display's";
}

}  // namespace

int run_calibrate_video(const CalibrateVideoCommand& cmd) {
  std::vector<cv::Mat> frames;
  for (const auto& f : cmd.frames) {
    cv::Mat image = geometry::read_image_file(f);
    if (image.depth() != CV_8U && image.depth() != CV_16U)
      throw base::InputError(f.string() + ": expected an 8- or 16-bit image as grabbed");
    if (!frames.empty() && image.size() != frames.front().size())
      throw base::InputError(f.string() + ": " + std::to_string(image.cols) + " x " + std::to_string(image.rows) + ", but " +
                             cmd.frames.front().string() + " is " + std::to_string(frames.front().cols) + " x " +
                             std::to_string(frames.front().rows) + ": give frames of one video output");
    frames.push_back(image);
  }
  geometry::VideoArea area;
  try {
    area = geometry::find_video_area(frames);
  } catch (const std::invalid_argument& e) {
    throw base::InputError(std::string("calibrate-video: ") + e.what());
  }
  const geometry::VideoMapping mapping = geometry::proposed_mapping(area, cmd.rotation_deg, cmd.mirror);
  node::log().info("image area {} ({}, {:.0f} % of its rectangle); {} text region(s)", rect_text(area.image_rect),
                   area.field_shape == geometry::FieldShape::Circle ? "a circle: image intensifier" : "a rectangle: flat detector",
                   100.0 * area.fill, area.text_regions.size());
  if (!area.image_text_searched)
    node::log().warn("graphics burned into the image itself were not looked for: {} (they are what stays the same while "
                     "the fluoroscopy's noise changes; give several frames of live fluoroscopy)",
                     frames.size() < 2 ? "one frame"
                                       : fmt::format("{:.0f} % of the image did not change across the frames", 100.0 * area.still_share));
  // The detector to check against: as given, else node.json's.
  std::optional<std::pair<int, int>> detector;
  if (cmd.detector_px.size() == 2) detector = {cmd.detector_px[0], cmd.detector_px[1]};
  std::optional<nlohmann::ordered_json> node_json;
  // With zoom modes the picture shows each mode's image as the C-arm delivers it (turned and
  // flipped as the mode says), not the physical detector: checked against every mode's.
  std::vector<std::pair<int, int>> mode_images;
  if (!cmd.node.empty()) {
    node_json = read_node_json(cmd.node);
    if (!detector && node_json->contains("zoom_modes")) {
      for (const geometry::ZoomMode& z : read_node_config(cmd.node).zoom_modes)
        mode_images.push_back(geometry::frame_size_px(std::nullopt, z));
      detector = mode_images.front();
    } else if (!detector && node_json->contains("detector") && (*node_json)["detector"].is_object()) {
      const auto& d = (*node_json)["detector"];
      if (d.contains("cols") && d.contains("rows") && d["cols"].is_number_integer() && d["rows"].is_number_integer())
        detector = {d["cols"].get<int>(), d["rows"].get<int>()};
    }
  }
  std::string problem = detector ? misfit(mapping, detector->first, detector->second) : std::string();
  for (const auto& [cols, rows] : mode_images)
    if (problem.empty() && (problem = misfit(mapping, cols, rows), !problem.empty())) detector = {cols, rows};
  if (detector && problem.empty())
    node::log().info("fits the {} x {} detector: {:.3f} video pixels per detector pixel", detector->first, detector->second,
                     geometry::VideoToDetector(mapping, detector->first, detector->second).video_px_per_detector_px());
  // Written either way, for the operator to look at and correct.
  geometry::write_video_mapping(cmd.out, mapping);
  node::log().info("wrote {}", cmd.out.string());
  if (!cmd.picture.empty()) {
    geometry::write_image_file(cmd.picture, calibration_picture(frames, area, mapping, frames.size()));
    node::log().info("picture: {}", cmd.picture.string());
  }
  if (!problem.empty()) {
    node::log().error("the mapping does not fit the {} x {} detector: {}{}", detector->first, detector->second, problem,
                      node_json ? "; " + cmd.node.string() + " left as it was" : "");
    return 1;
  }
  if (node_json) {
    point_node_config_at(cmd.node, *node_json, cmd.out);
    node::log().info("{} now names {} as its \"video_mapping\"", cmd.node.string(), cmd.out.string());
  }
  return 0;
}

}  // namespace evar::app
