#include "evar/geometry/zoom_mode.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <set>
#include <stdexcept>
#include <utility>

#include "evar/geometry/image_header.hpp"
#include "evar/geometry/json_fields.hpp"
#include "mesh_formats.hpp"

namespace evar::geometry {

namespace {

constexpr int kMaxImagePx = 16384;

std::string number_text(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

}  // namespace

ZoomMode centred_zoom_mode(int number, std::string name, int cols, int rows, double spacing_mm) {
  ZoomMode z;
  z.number = number;
  z.name = std::move(name);
  z.cols = cols;
  z.rows = rows;
  z.row_spacing_mm = z.col_spacing_mm = spacing_mm;
  z.width_mm = cols * spacing_mm;
  z.height_mm = rows * spacing_mm;
  return z;
}

DetectorSpec image_detector(const ZoomMode& mode) {
  return {mode.cols, mode.rows, mode.row_spacing_mm, mode.col_spacing_mm};
}

Eigen::Vector2d field_centre_mm(const DetectorSpec& detector, const ZoomMode& mode) {
  if (!mode.origin_rows_cols) return Eigen::Vector2d::Zero();
  // The detector's top-left corner lies half its extent from the central ray; the field's
  // corner the origin's elements further; its centre half its own extent on.
  const Eigen::Vector2d& o = *mode.origin_rows_cols;
  return {(o.y() - 0.5 * detector.cols) * detector.col_spacing_mm + 0.5 * mode.cols * mode.col_spacing_mm,
          (o.x() - 0.5 * detector.rows) * detector.row_spacing_mm + 0.5 * mode.rows * mode.row_spacing_mm};
}

CArmView zoom_view(const DetectorSpec& detector, const ZoomMode& mode, double primary_deg, double secondary_deg,
                   double sid_mm, double sod_mm) {
  CArmView v = view_of(image_detector(mode), primary_deg, secondary_deg, sid_mm, sod_mm);
  const Eigen::Vector2d c = field_centre_mm(detector, mode);
  if (c.isZero()) return v;  // centred: the angles and distances say it all
  ProjectionMatrix P = projection_matrix(v);
  // u' = u − c_x / col_spacing (and v alike) on homogeneous pixels: rows 0 and 1 less the
  // shift times row 2.
  P.row(0) -= (c.x() / mode.col_spacing_mm) * P.row(2);
  P.row(1) -= (c.y() / mode.row_spacing_mm) * P.row(2);
  v.projection_matrix = P;
  return v;
}

std::optional<VideoMapping> frame_mapping(const std::optional<VideoMapping>& display, const ZoomMode& mode) {
  const bool round = mode.shape == FieldShape::Circle;
  if (!display) {
    if (mode.rotation_deg == 0 && !mode.horizontal_flip && !round) return std::nullopt;
    const bool across = mode.rotation_deg % 180 != 0;
    VideoMapping m;
    m.video_cols = across ? mode.rows : mode.cols;
    m.video_rows = across ? mode.cols : mode.rows;
    m.image_rect = {0, 0, static_cast<double>(m.video_cols), static_cast<double>(m.video_rows)};
    m.rotation_deg = mode.rotation_deg;
    m.mirror = mode.horizontal_flip;
    m.field_shape = mode.shape;
    return m;
  }
  // shown = F^m2 R^r2 · F^f1 R^r1 · field, and R F = F R⁻¹ (a mirror turns a rotation back):
  // F^(f1 xor m2) R^(r1 ± r2), minus where the field was mirrored.
  VideoMapping m = *display;
  const int r2 = mode.horizontal_flip ? 360 - display->rotation_deg : display->rotation_deg;
  m.rotation_deg = (mode.rotation_deg + r2) % 360;
  m.mirror = mode.horizontal_flip != display->mirror;
  if (round) m.field_shape = FieldShape::Circle;
  return m;
}

std::pair<int, int> frame_size_px(const std::optional<VideoMapping>& display, const ZoomMode& mode) {
  if (display) return {display->video_cols, display->video_rows};
  return mode.rotation_deg % 180 != 0 ? std::pair{mode.rows, mode.cols} : std::pair{mode.cols, mode.rows};
}

std::string zoom_mode_problem(const ZoomMode& m, const DetectorSpec& detector) {
  if (m.number < 1 || m.number > 255) return "mode: must be 1-255 (the C-arm link's number for it), found " + std::to_string(m.number);
  if (m.name.empty()) return "name: empty; give the name the C-arm shows for the mode";
  if (m.cols < 1 || m.rows < 1 || m.cols > kMaxImagePx || m.rows > kMaxImagePx)
    return "image_size_px: " + std::to_string(m.cols) + " x " + std::to_string(m.rows) + "; each must be 1-16384";
  if (std::int64_t{m.cols} * m.rows > kMaxImagePixels)
    return "image_size_px: " + std::to_string(m.cols) + " x " + std::to_string(m.rows) + " pixels; at most " +
           std::to_string(kMaxImagePixels) + " in all (the largest image evarnode reads)";
  if (!(m.row_spacing_mm > 0) || !(m.col_spacing_mm > 0) || !std::isfinite(m.row_spacing_mm) || !std::isfinite(m.col_spacing_mm))
    return "imager_pixel_spacing_mm: must be positive";
  if (m.rotation_deg % 90 != 0 || m.rotation_deg < 0 || m.rotation_deg >= 360)
    return "field_of_view_rotation_deg: must be 0, 90, 180 or 270, found " + std::to_string(m.rotation_deg);
  if (m.shape == FieldShape::Circle && (m.cols != m.rows || std::abs(m.row_spacing_mm - m.col_spacing_mm) > 1e-9 * m.col_spacing_mm))
    return "field_of_view_shape: a ROUND field needs a square image of square pixels, found " + std::to_string(m.cols) +
           " x " + std::to_string(m.rows) + " pixels of " + number_text(m.row_spacing_mm) + " x " + number_text(m.col_spacing_mm) + " mm";
  // The dimensions say the same as the pixels, to within two of them either way.
  const double width_px = m.width_mm / m.col_spacing_mm, height_px = m.height_mm / m.row_spacing_mm;
  if (!(std::abs(width_px - m.cols) <= 2.0) || !(std::abs(height_px - m.rows) <= 2.0))
    return "field_of_view_dimensions_mm: " + number_text(m.height_mm) + " x " + number_text(m.width_mm) + " mm are " +
           number_text(height_px) + " x " + number_text(width_px) + " pixels of imager_pixel_spacing_mm, not the image's " +
           std::to_string(m.rows) + " x " + std::to_string(m.cols) + " (rows x columns)";
  // On the detector, to within one element.
  const Eigen::Vector2d c = field_centre_mm(detector, m);
  const double half_w = 0.5 * detector.cols * detector.col_spacing_mm, half_h = 0.5 * detector.rows * detector.row_spacing_mm;
  const double slack_w = detector.col_spacing_mm, slack_h = detector.row_spacing_mm;
  if (std::abs(c.x()) + 0.5 * m.cols * m.col_spacing_mm > half_w + slack_w ||
      std::abs(c.y()) + 0.5 * m.rows * m.row_spacing_mm > half_h + slack_h)
    return std::string(m.origin_rows_cols ? "field_of_view_origin_px: the field placed there" : "field_of_view_dimensions_mm: the field") +
           " (" + number_text(m.width_mm) + " x " + number_text(m.height_mm) + " mm) reaches past the detector's " +
           number_text(2 * half_w) + " x " + number_text(2 * half_h) + " mm (node.json detector: the physical detector when zoom modes are given)";
  return "";
}

namespace {

ZoomMode parse_zoom_mode(const nlohmann::json& j, const DetectorSpec& detector, const std::filesystem::path& source,
                         const std::string& prefix) {
  using detail::bad_field;
  const auto field = [&](const std::string& name) { return prefix + name; };
  if (!j.is_object()) bad_field(source, prefix.substr(0, prefix.size() - 1), std::string("expected a JSON object, found ") + j.type_name());
  static const std::array<const char*, 9> known{"mode", "name", "field_of_view_shape", "field_of_view_dimensions_mm",
                                                "image_size_px", "imager_pixel_spacing_mm", "field_of_view_origin_px",
                                                "field_of_view_rotation_deg", "field_of_view_horizontal_flip"};
  for (const auto& [key, value] : j.items())
    if (std::find_if(known.begin(), known.end(), [&](const char* k) { return key == k; }) == known.end())
      bad_field(source, field(key),
                "not a field of a zoom mode (mode, name, field_of_view_shape, field_of_view_dimensions_mm, image_size_px, "
                "imager_pixel_spacing_mm, field_of_view_origin_px, field_of_view_rotation_deg, "
                "field_of_view_horizontal_flip): a misspelt one would be ignored, so none is");
  ZoomMode m;
  const auto& number = detail::member(source, j, "mode", field("mode"));
  if (!number.is_number_integer() || number.get<long long>() < 1 || number.get<long long>() > 255)
    bad_field(source, field("mode"), "must be a whole number 1-255 (the C-arm link's number for the mode), found " + number.dump());
  m.number = number.get<int>();
  const auto& name = detail::member(source, j, "name", field("name"));
  if (!name.is_string() || name.get<std::string>().empty())
    bad_field(source, field("name"), "must be the name the C-arm shows for the mode, found " + name.dump());
  m.name = name.get<std::string>();
  if (const auto it = j.find("field_of_view_shape"); it != j.end()) {
    if (*it == "RECTANGLE") m.shape = FieldShape::Rectangle;
    else if (*it == "ROUND") m.shape = FieldShape::Circle;
    else bad_field(source, field("field_of_view_shape"), "must be \"RECTANGLE\" or \"ROUND\" (DICOM's terms), found " + it->dump());
  }
  const auto& dims = detail::member(source, j, "field_of_view_dimensions_mm", field("field_of_view_dimensions_mm"));
  if (m.shape == FieldShape::Circle) {
    const Eigen::VectorXd d = detail::number_array(source, dims, field("field_of_view_dimensions_mm") + " (ROUND: [diameter])", 1);
    m.height_mm = m.width_mm = d(0);
  } else {
    const Eigen::VectorXd d = detail::number_array(source, dims, field("field_of_view_dimensions_mm") + " ([rows, columns] extent)", 2);
    m.height_mm = d(0);
    m.width_mm = d(1);
  }
  const Eigen::VectorXd size = detail::number_array(source, detail::member(source, j, "image_size_px", field("image_size_px")),
                                                    field("image_size_px") + " ([columns, rows])", 2);
  for (int k = 0; k < 2; ++k)
    if (size(k) != std::floor(size(k)))
      bad_field(source, field("image_size_px[" + std::to_string(k) + "]"), "must be a whole number of pixels, found " + number_text(size(k)));
  m.cols = static_cast<int>(std::clamp(size(0), -1.0, 1e6));
  m.rows = static_cast<int>(std::clamp(size(1), -1.0, 1e6));
  const Eigen::VectorXd sp = detail::number_array(
      source, detail::member(source, j, "imager_pixel_spacing_mm", field("imager_pixel_spacing_mm")),
      field("imager_pixel_spacing_mm") + " ([row spacing, column spacing])", 2);
  m.row_spacing_mm = sp(0);
  m.col_spacing_mm = sp(1);
  if (const auto it = j.find("field_of_view_origin_px"); it != j.end()) {
    const Eigen::VectorXd o = detail::number_array(source, *it, field("field_of_view_origin_px") + " ([rows, columns] of detector elements)", 2);
    m.origin_rows_cols = Eigen::Vector2d(o(0), o(1));
  }
  if (const auto it = j.find("field_of_view_rotation_deg"); it != j.end()) {
    const bool quarter = it->is_number_integer() && (*it == 0 || *it == 90 || *it == 180 || *it == 270);
    if (!quarter) bad_field(source, field("field_of_view_rotation_deg"), "must be 0, 90, 180 or 270 (clockwise), found " + it->dump());
    m.rotation_deg = it->get<int>();
  }
  if (const auto it = j.find("field_of_view_horizontal_flip"); it != j.end()) {
    if (!it->is_boolean()) bad_field(source, field("field_of_view_horizontal_flip"), "must be true or false, found " + it->dump());
    m.horizontal_flip = it->get<bool>();
  }
  if (const auto p = zoom_mode_problem(m, detector); !p.empty()) detail::fail(source, prefix + p);
  return m;
}

}  // namespace

std::vector<ZoomMode> parse_zoom_modes(const nlohmann::json& array, const DetectorSpec& detector,
                                       const std::filesystem::path& source, const std::string& prefix) {
  const std::string name = prefix + "zoom_modes";
  if (!array.is_array() || array.empty())
    detail::bad_field(source, name, "expected an array of one or more zoom modes, found " + array.dump());
  std::vector<ZoomMode> modes;
  std::set<int> numbers;
  for (std::size_t k = 0; k < array.size(); ++k) {
    const std::string at = name + "[" + std::to_string(k) + "].";
    modes.push_back(parse_zoom_mode(array[k], detector, source, at));
    if (!numbers.insert(modes.back().number).second)
      detail::bad_field(source, at + "mode", std::to_string(modes.back().number) + " is given twice; each mode needs its own number");
  }
  return modes;
}

nlohmann::json zoom_modes_json(const std::vector<ZoomMode>& modes) {
  nlohmann::json a = nlohmann::json::array();
  for (const ZoomMode& m : modes) {
    nlohmann::json j{{"mode", m.number},
                     {"name", m.name},
                     {"field_of_view_shape", m.shape == FieldShape::Circle ? "ROUND" : "RECTANGLE"},
                     {"field_of_view_dimensions_mm", m.shape == FieldShape::Circle ? nlohmann::json::array({m.width_mm})
                                                                                     : nlohmann::json::array({m.height_mm, m.width_mm})},
                     {"image_size_px", {m.cols, m.rows}},
                     {"imager_pixel_spacing_mm", {m.row_spacing_mm, m.col_spacing_mm}},
                     {"field_of_view_rotation_deg", m.rotation_deg},
                     {"field_of_view_horizontal_flip", m.horizontal_flip}};
    if (m.origin_rows_cols) j["field_of_view_origin_px"] = {m.origin_rows_cols->x(), m.origin_rows_cols->y()};
    a.push_back(std::move(j));
  }
  return a;
}

const ZoomMode* find_zoom_mode(const std::vector<ZoomMode>& modes, int number) {
  const auto it = std::find_if(modes.begin(), modes.end(), [&](const ZoomMode& m) { return m.number == number; });
  return it == modes.end() ? nullptr : &*it;
}

}  // namespace evar::geometry
