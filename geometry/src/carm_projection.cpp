#include "evar/geometry/carm_projection.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "evar/base/atomic_file.hpp"
#include "evar/base/input_error.hpp"
#include "evar/geometry/json_fields.hpp"
#include "mesh_formats.hpp"

namespace evar::geometry {

namespace {
constexpr double kDegToRad = std::numbers::pi / 180.0;
constexpr int kMaxDetectorPx = 16384;

void check_view(const CArmView& v) {
  if (!(v.source_to_isocenter_mm > 0.0 && v.source_to_isocenter_mm < v.source_to_detector_mm))
    throw std::invalid_argument("C-arm view: the isocenter must lie between source and detector (0 < SOD < SID)");
  if (v.detector_cols <= 0 || v.detector_rows <= 0 || v.detector_cols > kMaxDetectorPx || v.detector_rows > kMaxDetectorPx)
    throw std::invalid_argument("C-arm view: detector size must be 1 to 16384 pixels each way");
  if (!(v.row_spacing_mm > 0.0) || !(v.col_spacing_mm > 0.0))
    throw std::invalid_argument("C-arm view: pixel spacing must be positive");
}

// A camera: finite, with a non-singular left 3x3 block; a calibrated view's matrix must also
// see the isocenter in front of its source.
std::string projection_matrix_problem(const ProjectionMatrix& P, bool isocenter_in_front) {
  if (!P.allFinite()) return "not finite";
  const Eigen::Matrix3d M = P.leftCols<3>();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(M);
  const auto s = svd.singularValues();
  if (!(s(2) > 1e-12 * s(0))) return "its left 3x3 block is singular (not a finite camera)";
  // w of the isocenter (the world origin) is P[2][3]: positive in front of the source.
  if (isocenter_in_front && !(P(2, 3) > 0.0))
    return "the isocenter (world origin) is not in front of the source: P[2][3] must be > 0 "
           "(scale the matrix so that the third row gives positive depth)";
  return {};
}
}  // namespace

Eigen::Matrix3d carm_rotation(double primary_angle_deg, double secondary_angle_deg) {
  return (Eigen::AngleAxisd(primary_angle_deg * kDegToRad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(-secondary_angle_deg * kDegToRad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

ProjectionMatrix projection_matrix(const CArmView& view) {
  if (view.projection_matrix) {
    if (const auto problem = projection_matrix_problem(*view.projection_matrix, true); !problem.empty())
      throw std::invalid_argument("C-arm view: projection matrix " + problem);
    return *view.projection_matrix;
  }
  check_view(view);
  const Eigen::Matrix3d M = carm_rotation(view.primary_angle_deg, view.secondary_angle_deg);
  const Eigen::Vector3d d = M * Eigen::Vector3d(0, -1, 0);
  const Eigen::Vector3d u = M * Eigen::Vector3d(1, 0, 0);
  const Eigen::Vector3d v = M * Eigen::Vector3d(0, 0, -1);
  const Eigen::Vector3d S = -view.source_to_isocenter_mm * d;
  Eigen::Matrix3d Rc;  // camera coordinates (along û, v̂, d) of X − S
  Rc << u.transpose(), v.transpose(), d.transpose();
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  K(0, 0) = view.source_to_detector_mm / view.col_spacing_mm;
  K(1, 1) = view.source_to_detector_mm / view.row_spacing_mm;
  K(0, 2) = 0.5 * (view.detector_cols - 1);
  K(1, 2) = 0.5 * (view.detector_rows - 1);
  ProjectionMatrix P;
  P.leftCols<3>() = K * Rc;
  P.col(3) = -K * Rc * S;
  return P;
}

ProjectionMatrix registered(const ProjectionMatrix& P, const Eigen::Matrix4d& ct_to_carm) { return P * ct_to_carm; }

PinholeCamera pinhole_camera(const ProjectionMatrix& P) {
  if (const auto problem = projection_matrix_problem(P, false); !problem.empty())
    throw std::invalid_argument("projection matrix " + problem);
  PinholeCamera c;
  c.M_inverse = P.leftCols<3>().inverse();
  c.source_mm = -c.M_inverse * P.col(3);
  c.direction = P.row(2).head<3>().transpose().normalized();  // w grows along it
  return c;
}

std::optional<Eigen::Vector2d> project(const ProjectionMatrix& P, const Eigen::Vector3d& X_mm) {
  const Eigen::Vector3d x = P * X_mm.homogeneous();
  // Closer than a micrometre to the source plane (or behind it): no image.
  if (!(x.z() > 1e-3 * P.row(2).head<3>().norm())) return std::nullopt;
  return x.head<2>() / x.z();
}

double depth_mm(const ProjectionMatrix& P, const Eigen::Vector3d& X_mm) {
  return P.row(2).dot(X_mm.homogeneous()) / P.row(2).head<3>().norm();
}

Eigen::Vector3d back_projected_ray(const PinholeCamera& camera, const Eigen::Vector2d& pixel) {
  return (camera.M_inverse * pixel.homogeneous()).normalized();
}

double device_shadow_width_px(const CArmView& view, double diameter_mm) {
  return diameter_mm * view.source_to_detector_mm / view.source_to_isocenter_mm /
         std::min(view.row_spacing_mm, view.col_spacing_mm);
}

ViewGeometryFile read_view_geometry_file(const std::filesystem::path& path) {
  using detail::bad_field;
  using detail::member;
  using detail::number_array;
  using detail::number_field;
  const auto root = detail::parse_json_file(path);
  if (!root.is_object()) detail::fail(path, std::string("top level: expected a JSON object, found ") + root.type_name());
  CArmView v;
  v.primary_angle_deg = number_field(path, member(path, root, "primary_angle_deg", "primary_angle_deg"),
                                     "primary_angle_deg", -180.0, 180.0, "degrees (+ LAO, - RAO)");
  v.secondary_angle_deg = number_field(path, member(path, root, "secondary_angle_deg", "secondary_angle_deg"),
                                       "secondary_angle_deg", -90.0, 90.0, "degrees (+ CRA, - CAU)");
  v.source_to_detector_mm = number_field(path, member(path, root, "source_to_detector_mm", "source_to_detector_mm"),
                                         "source_to_detector_mm", 1.0, 5000.0, "mm");
  v.source_to_isocenter_mm = number_field(path, member(path, root, "source_to_isocenter_mm", "source_to_isocenter_mm"),
                                          "source_to_isocenter_mm", 1.0, 5000.0, "mm");
  if (!(v.source_to_isocenter_mm < v.source_to_detector_mm))
    bad_field(path, "source_to_isocenter_mm",
              "must be less than source_to_detector_mm (the isocenter lies between source and detector)");
  const auto& size = member(path, root, "detector_size_px", "detector_size_px");
  const Eigen::VectorXd s = number_array(path, size, "detector_size_px", 2);
  for (int k = 0; k < 2; ++k)
    if (s(k) != std::floor(s(k)) || s(k) < 1 || s(k) > kMaxDetectorPx)
      bad_field(path, "detector_size_px[" + std::to_string(k) + "]",
                "must be a whole number of pixels from 1 to 16384, found " + size[static_cast<std::size_t>(k)].dump());
  v.detector_cols = static_cast<int>(s(0));
  v.detector_rows = static_cast<int>(s(1));
  const auto& spacing = member(path, root, "pixel_spacing_mm", "pixel_spacing_mm");
  number_array(path, spacing, "pixel_spacing_mm", 2);
  v.row_spacing_mm = number_field(path, spacing[0], "pixel_spacing_mm[0] (row spacing)", 1e-3, 10.0, "mm");
  v.col_spacing_mm = number_field(path, spacing[1], "pixel_spacing_mm[1] (column spacing)", 1e-3, 10.0, "mm");
  if (const auto it = root.find("projection_matrix"); it != root.end() && !it->is_null()) {
    if (!it->is_array() || it->size() != 3)
      bad_field(path, "projection_matrix", "expected 3 rows of 4 numbers, found " + std::string(it->type_name()) +
                                               (it->is_array() ? " of " + std::to_string(it->size()) + " rows" : ""));
    ProjectionMatrix P;
    for (int r = 0; r < 3; ++r)
      P.row(r) = number_array(path, (*it)[static_cast<std::size_t>(r)], "projection_matrix[" + std::to_string(r) + "]", 4)
                     .transpose();
    if (const auto problem = projection_matrix_problem(P, true); !problem.empty()) bad_field(path, "projection_matrix", problem);
    v.projection_matrix = P;
  }
  ViewGeometryFile file{v, std::nullopt};
  if (const auto it = root.find("video_mapping"); it != root.end() && !it->is_null()) {
    file.video_mapping = parse_video_mapping(*it, path, "video_mapping.");
    try {
      const VideoToDetector check(*file.video_mapping, v.detector_cols, v.detector_rows);
    } catch (const std::invalid_argument& e) {
      bad_field(path, "video_mapping", std::string(e.what()).substr(std::string("video mapping: ").size()));
    }
  }
  return file;
}

CArmView read_view_geometry(const std::filesystem::path& path) { return read_view_geometry_file(path).view; }

void write_view_geometry(const std::filesystem::path& path, const CArmView& view,
                         const std::optional<VideoMapping>& video_mapping) {
  nlohmann::json j;
  j["primary_angle_deg"] = view.primary_angle_deg;
  j["secondary_angle_deg"] = view.secondary_angle_deg;
  j["source_to_detector_mm"] = view.source_to_detector_mm;
  j["source_to_isocenter_mm"] = view.source_to_isocenter_mm;
  j["detector_size_px"] = {view.detector_cols, view.detector_rows};
  j["pixel_spacing_mm"] = {view.row_spacing_mm, view.col_spacing_mm};
  if (view.projection_matrix) {
    nlohmann::json rows = nlohmann::json::array();
    for (int r = 0; r < 3; ++r) {
      nlohmann::json row = nlohmann::json::array();
      for (int c = 0; c < 4; ++c) row.push_back((*view.projection_matrix)(r, c));
      rows.push_back(row);
    }
    j["projection_matrix"] = rows;
  }
  if (video_mapping) j["video_mapping"] = video_mapping_json(*video_mapping);
  base::write_file_atomically(path, j.dump(2) + "\n");
}

Eigen::Matrix4d read_registration(const std::filesystem::path& path) {
  const auto root = detail::parse_json_file(path);
  if (!root.is_object()) detail::fail(path, std::string("top level: expected a JSON object, found ") + root.type_name());
  const auto& m = detail::member(path, root, "matrix", "matrix");
  if (!m.is_array() || m.size() != 4)
    detail::bad_field(path, "matrix", "expected 4 rows of 4 numbers (row-major, mm)");
  Eigen::Matrix4d T;
  for (int r = 0; r < 4; ++r)
    T.row(r) = detail::number_array(path, m[static_cast<std::size_t>(r)], "matrix[" + std::to_string(r) + "]", 4).transpose();
  if ((T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9)
    detail::bad_field(path, "matrix[3]", "the last row must be [0, 0, 0, 1] (an affine transform)");
  const Eigen::Matrix3d A = T.topLeftCorner<3, 3>();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(A);
  const auto s = svd.singularValues();
  if (A.determinant() <= 0.0)
    detail::bad_field(path, "matrix",
                      "the 3x3 part mirrors space (determinant <= 0); a registration never does: check for an "
                      "LPS/RAS mix-up or a transposed matrix");
  // Registration is rigid, perhaps with a little calibration scale; more is a unit mix-up.
  if (s(0) > 1.1 || s(2) < 0.9)
    detail::bad_field(path, "matrix",
                      "the 3x3 part scales by " + std::to_string(s(2)) + " to " + std::to_string(s(0)) +
                          "; a CT to C-arm registration is rigid (check units: millimetres)");
  return T;
}

}  // namespace evar::geometry
