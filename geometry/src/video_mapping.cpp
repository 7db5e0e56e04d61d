#include "evar/geometry/video_mapping.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "evar/base/atomic_file.hpp"
#include "evar/geometry/json_fields.hpp"
#include "mesh_formats.hpp"

namespace evar::geometry {

namespace {

constexpr int kMaxVideoPx = 16384;
// Display pixels are square: a rectangle whose aspect differs from the turned detector's by
// more than this is a wrong rotation or a wrong rectangle.
constexpr double kAspectTolerance = 0.02;
constexpr const char* kFormat = "evarnode-video-mapping";

std::string rect_text(const PixelRect& r) {
  std::ostringstream out;
  out << '[' << r.x << ", " << r.y << ", " << r.width << ", " << r.height << ']';
  return out.str();
}

std::string number_text(double value) {
  std::ostringstream out;
  out.precision(4);
  out << value;
  return out.str();
}

// "" when `r` lies inside a frame of cols × rows with a positive size.
std::string rect_problem(const PixelRect& r, int cols, int rows) {
  if (!(std::isfinite(r.x) && std::isfinite(r.y) && std::isfinite(r.width) && std::isfinite(r.height)))
    return "holds a number that is not finite";
  if (!(r.width > 0.0 && r.height > 0.0)) return "width and height must be positive, found " + rect_text(r);
  if (r.x < 0.0 || r.y < 0.0 || r.x + r.width > cols || r.y + r.height > rows)
    return rect_text(r) + " reaches outside the " + std::to_string(cols) + " x " + std::to_string(rows) +
           " frame ([x, y, width, height] in video pixels, x + width <= " + std::to_string(cols) +
           ", y + height <= " + std::to_string(rows) + ")";
  return "";
}

}  // namespace

std::string video_mapping_problem(const VideoMapping& m) {
  if (m.video_cols < 1 || m.video_rows < 1 || m.video_cols > kMaxVideoPx || m.video_rows > kMaxVideoPx)
    return "video_size_px: must be 1 to 16384 pixels each, found [" + std::to_string(m.video_cols) + ", " +
           std::to_string(m.video_rows) + "]";
  if (const auto p = rect_problem(m.image_rect, m.video_cols, m.video_rows); !p.empty()) return "image_rect_px: " + p;
  if (m.rotation_deg != 0 && m.rotation_deg != 90 && m.rotation_deg != 180 && m.rotation_deg != 270)
    return "rotation_deg: must be 0, 90, 180 or 270 (clockwise as shown), found " + std::to_string(m.rotation_deg);
  for (std::size_t k = 0; k < m.text_regions.size(); ++k)
    if (const auto p = rect_problem(m.text_regions[k], m.video_cols, m.video_rows); !p.empty())
      return "text_regions_px[" + std::to_string(k) + "]: " + p;
  return "";
}

Eigen::Matrix2d turn_and_mirror(int rotation_deg, bool mirror) {
  if (rotation_deg % 90 != 0 || rotation_deg < 0 || rotation_deg > 270)
    throw std::invalid_argument("picture turn: rotation " + std::to_string(rotation_deg) +
                                " degrees is not 0, 90, 180 or 270");
  // A clockwise quarter turn as seen takes (x, y) to (−y, x); the mirror takes x to −x.
  Eigen::Matrix2d Q = Eigen::Matrix2d::Identity();
  const Eigen::Matrix2d quarter{{0.0, -1.0}, {1.0, 0.0}};
  for (int k = 0; k < rotation_deg / 90; ++k) Q = quarter * Q;
  if (mirror) Q.row(0) *= -1.0;
  return Q;
}

VideoToDetector::VideoToDetector(const VideoMapping& mapping, int detector_cols, int detector_rows)
    : detector_cols_(detector_cols),
      detector_rows_(detector_rows),
      video_cols_(mapping.video_cols),
      video_rows_(mapping.video_rows) {
  if (const auto p = video_mapping_problem(mapping); !p.empty()) throw std::invalid_argument("video mapping: " + p);
  if (detector_cols < 1 || detector_rows < 1) throw std::invalid_argument("video mapping: the detector has no pixels");
  const double W = detector_cols, H = detector_rows;
  const bool turned = mapping.rotation_deg == 90 || mapping.rotation_deg == 270;
  const double shown_w = turned ? H : W, shown_h = turned ? W : H;  // the detector image as turned
  const double sx = mapping.image_rect.width / shown_w, sy = mapping.image_rect.height / shown_h;
  if (std::abs(sx / sy - 1.0) > kAspectTolerance)
    throw std::invalid_argument(
        "video mapping: image_rect_px " + rect_text(mapping.image_rect) + " is " +
        number_text(mapping.image_rect.width / mapping.image_rect.height) + " times as wide as high, the " +
        std::to_string(detector_cols) + " x " + std::to_string(detector_rows) + " detector turned by " +
        std::to_string(mapping.rotation_deg) + " degrees " + number_text(shown_w / shown_h) +
        " (display pixels are square): check rotation_deg and the rectangle");

  // On pixel edges (centre + ½): turn, mirror, scale into the rectangle. The turned and
  // mirrored picture's corner goes back to the origin by r (turned) and m (mirrored).
  Eigen::Vector2d r = Eigen::Vector2d::Zero();
  switch (mapping.rotation_deg) {
    case 90: r << H, 0; break;
    case 180: r << W, H; break;
    case 270: r << 0, W; break;
    default: break;
  }
  const Eigen::Matrix2d M = turn_and_mirror(0, mapping.mirror);
  const Eigen::Vector2d m(mapping.mirror ? shown_w : 0.0, 0.0);
  const Eigen::Matrix2d S = Eigen::Vector2d(sx, sy).asDiagonal();
  const Eigen::Vector2d origin(mapping.image_rect.x, mapping.image_rect.y), half(0.5, 0.5);
  const Eigen::Matrix2d L = S * turn_and_mirror(mapping.rotation_deg, mapping.mirror);
  const Eigen::Vector2d t = L * half + S * (M * r + m) + origin - half;
  forward_ << L, t;
  const Eigen::Matrix2d Li = L.inverse();
  inverse_ << Li, -Li * t;
}

std::string video_mapping_fit_problem(const VideoMapping& mapping, int detector_cols, int detector_rows) {
  try {
    const VideoToDetector fits(mapping, detector_cols, detector_rows);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

double VideoToDetector::video_px_per_detector_px() const {
  return std::sqrt(std::abs(forward_.leftCols<2>().determinant()));
}

Eigen::Vector2d VideoToDetector::to_video(const Eigen::Vector2d& p) const {
  return forward_.leftCols<2>() * p + forward_.col(2);
}

Eigen::Vector2d VideoToDetector::to_detector(const Eigen::Vector2d& p) const {
  return inverse_.leftCols<2>() * p + inverse_.col(2);
}

VideoMapping parse_video_mapping(const nlohmann::json& j, const std::filesystem::path& source, const std::string& prefix) {
  using detail::bad_field;
  const auto field = [&](const std::string& name) { return prefix + name; };
  if (!j.is_object()) bad_field(source, prefix.empty() ? "top level" : prefix.substr(0, prefix.size() - 1),
                                std::string("expected a JSON object, found ") + j.type_name());
  static const std::array<const char*, 8> known{"format", "version", "video_size_px", "image_rect_px",
                                                "mirror", "rotation_deg", "field_shape", "text_regions_px"};
  for (const auto& [key, value] : j.items())
    if (std::find_if(known.begin(), known.end(), [&](const char* k) { return key == k; }) == known.end())
      bad_field(source, field(key),
                "not a field of a video mapping (format, version, video_size_px, image_rect_px, mirror, rotation_deg, "
                "field_shape, text_regions_px): a misspelt one would be ignored, so none is");
  const auto& format = detail::member(source, j, "format", field("format"));
  if (!format.is_string() || format.get<std::string>() != kFormat)
    bad_field(source, field("format"), std::string("must be \"") + kFormat + "\", found " + format.dump());
  const auto& version = detail::member(source, j, "version", field("version"));
  if (!version.is_number_integer() || version.get<long long>() != 1)
    bad_field(source, field("version"), "this evarnode reads version 1, found " + version.dump());

  VideoMapping m;
  const auto& size = detail::member(source, j, "video_size_px", field("video_size_px"));
  const Eigen::VectorXd s = detail::number_array(source, size, field("video_size_px"), 2);
  for (int k = 0; k < 2; ++k)
    if (s(k) != std::floor(s(k)) || s(k) < 1 || s(k) > kMaxVideoPx)
      bad_field(source, field("video_size_px[" + std::to_string(k) + "]"),
                "must be a whole number of pixels from 1 to 16384, found " + size[static_cast<std::size_t>(k)].dump());
  m.video_cols = static_cast<int>(s(0));
  m.video_rows = static_cast<int>(s(1));
  const auto rect = [&](const nlohmann::json& v, const std::string& name) {
    const Eigen::VectorXd r = detail::number_array(source, v, name, 4);
    return PixelRect{r(0), r(1), r(2), r(3)};
  };
  m.image_rect = rect(detail::member(source, j, "image_rect_px", field("image_rect_px")), field("image_rect_px"));
  if (const auto it = j.find("mirror"); it != j.end()) {
    if (!it->is_boolean()) bad_field(source, field("mirror"), "must be true or false, found " + it->dump());
    m.mirror = it->get<bool>();
  }
  if (const auto it = j.find("rotation_deg"); it != j.end()) {
    const bool quarter = it->is_number_integer() && (*it == 0 || *it == 90 || *it == 180 || *it == 270);
    if (!quarter) bad_field(source, field("rotation_deg"), "must be 0, 90, 180 or 270 (clockwise as shown), found " + it->dump());
    m.rotation_deg = it->get<int>();
  }
  if (const auto it = j.find("field_shape"); it != j.end()) {
    if (*it == "rectangle")
      m.field_shape = FieldShape::Rectangle;
    else if (*it == "circle")
      m.field_shape = FieldShape::Circle;
    else
      bad_field(source, field("field_shape"),
                "must be \"rectangle\" (a flat detector) or \"circle\" (an image intensifier), found " + it->dump());
  }
  if (const auto it = j.find("text_regions_px"); it != j.end()) {
    if (!it->is_array())
      bad_field(source, field("text_regions_px"), "expected an array of [x, y, width, height], found " + it->dump());
    for (std::size_t k = 0; k < it->size(); ++k)
      m.text_regions.push_back(rect((*it)[k], field("text_regions_px[" + std::to_string(k) + "]")));
  }
  if (const auto p = video_mapping_problem(m); !p.empty()) detail::fail(source, prefix + p);
  return m;
}

nlohmann::json video_mapping_json(const VideoMapping& m) {
  const auto rect = [](const PixelRect& r) { return nlohmann::json::array({r.x, r.y, r.width, r.height}); };
  nlohmann::json regions = nlohmann::json::array();
  for (const auto& r : m.text_regions) regions.push_back(rect(r));
  return {{"format", kFormat},
          {"version", 1},
          {"video_size_px", {m.video_cols, m.video_rows}},
          {"image_rect_px", rect(m.image_rect)},
          {"mirror", m.mirror},
          {"rotation_deg", m.rotation_deg},
          {"field_shape", m.field_shape == FieldShape::Circle ? "circle" : "rectangle"},
          {"text_regions_px", regions}};
}

VideoMapping read_video_mapping(const std::filesystem::path& path) {
  return parse_video_mapping(detail::parse_json_file(path), path);
}

void write_video_mapping(const std::filesystem::path& path, const VideoMapping& mapping) {
  if (const auto p = video_mapping_problem(mapping); !p.empty()) throw std::invalid_argument("video mapping: " + p);
  base::write_file_atomically(path, video_mapping_json(mapping).dump(2) + "\n");
}

}  // namespace evar::geometry
