#pragma once
// The C-arm projection model (docs/CARM_GEOMETRY.md has the derivation and a figure).
//
// World: patient LPS millimetres with the isocenter at the origin (x = Left, y = Posterior,
// z = Superior). Angles as DICOM PS3.3 C.8.7.5 defines them: primary + = LAO, − = RAO;
// secondary + = CRA, − = CAU; at 0/0 the patient faces the detector (AP: source posterior,
// detector anterior). With M = Rz(a)·Rx(−b):
//
//   viewing direction  d = M (0, −1, 0)   (source → detector)
//   source             S = −SOD·d
//   detector axes      û = M (1, 0, 0)  (columns, to the right),  v̂ = M (0, 0, −1)  (rows, down)
//   pixel              u = SID (X−S)·û / ((X−S)·d) / col_spacing + (cols − 1)/2
//                      v = SID (X−S)·v̂ / ((X−S)·d) / row_spacing + (rows − 1)/2
//
// so P = K [Rᵀ | −RᵀS] with R = [û v̂ d] and K = [SID/col_sp 0 (cols−1)/2; 0 SID/row_sp (rows−1)/2;
// 0 0 1]. Pixel (0, 0) is the centre of the top-left pixel; a point at the isocenter lands on
// the image centre and is magnified SID/SOD.
#include <Eigen/Core>
#include <filesystem>
#include <optional>

#include "evar/geometry/video_mapping.hpp"

namespace evar::geometry {

using ProjectionMatrix = Eigen::Matrix<double, 3, 4>;

/// One view's geometry, as in the view geometry JSON file (pinned by issue 3) or a DICOM
/// XA header.
struct CArmView {
  double primary_angle_deg = 0.0;       ///< + LAO, − RAO (−180 … 180)
  double secondary_angle_deg = 0.0;     ///< + CRA, − CAU (−90 … 90)
  double source_to_detector_mm = 0.0;   ///< SID
  double source_to_isocenter_mm = 0.0;  ///< SOD (< SID)
  int detector_cols = 0;                ///< image width (px)
  int detector_rows = 0;                ///< image height (px)
  double row_spacing_mm = 0.0;          ///< at the detector: between rows (along v)
  double col_spacing_mm = 0.0;          ///< at the detector: between columns (along u)
  /// A calibrated 3x4 matrix (world mm → homogeneous pixels); when set it wins over the
  /// angles and distances.
  std::optional<ProjectionMatrix> projection_matrix;
};

/// M = Rz(primary)·Rx(−secondary): the C-arm's rotation from its 0/0 position.
Eigen::Matrix3d carm_rotation(double primary_angle_deg, double secondary_angle_deg);

/// The view's projection matrix: the calibrated one if given, else built as above.
/// Throws std::invalid_argument for impossible geometry (SOD >= SID, non-positive sizes).
ProjectionMatrix projection_matrix(const CArmView& view);

/// P·T: projection of CT LPS points for a CT→C-arm registration T (4x4, rigid or affine).
ProjectionMatrix registered(const ProjectionMatrix& P, const Eigen::Matrix4d& ct_to_carm);

/// The geometry recovered from any finite projective camera P = K[R | −RS].
struct PinholeCamera {
  Eigen::Vector3d source_mm;      ///< centre of projection (null space of P)
  Eigen::Vector3d direction;      ///< unit principal axis, towards the detector
  Eigen::Matrix3d M_inverse;      ///< inverse of P's left 3x3 block (back-projection)
};
/// Throws std::invalid_argument if P is not finite or its left 3x3 block is singular (not a
/// camera). Any P = K[R | −RS] works, registered ones included; `direction` assumes the
/// scale gives positive depth in front of the source (as projection_matrix() does).
PinholeCamera pinhole_camera(const ProjectionMatrix& P);

/// Pixel position of a world point; nullopt when the point is at or behind the source.
std::optional<Eigen::Vector2d> project(const ProjectionMatrix& P, const Eigen::Vector3d& X_mm);

/// Distance (mm) from the source along the principal axis: the projective depth of X,
/// normalized so it reads in millimetres for matrices of any scale.
double depth_mm(const ProjectionMatrix& P, const Eigen::Vector3d& X_mm);

/// The unit direction from the source through pixel (u, v).
Eigen::Vector3d back_projected_ray(const PinholeCamera& camera, const Eigen::Vector2d& pixel);

/// Width (px) of the shadow a device of `diameter_mm` casts when it lies at the view's
/// isocenter: diameter × SID/SOD / pixel spacing (the finer of the two spacings).
double device_shadow_width_px(const CArmView& view, double diameter_mm);

/// A view geometry JSON file: the view, and its optional "video_mapping" (where the
/// detector image lies in the frames when they are a C-arm's video output, the monitor's
/// picture; none: the frames are the detector's).
struct ViewGeometryFile {
  CArmView view;
  std::optional<VideoMapping> video_mapping;
};
/// Reads one; InputError names the file and the field ("video_mapping.<field>", or the
/// mapping when its rectangle does not have the turned detector's shape).
ViewGeometryFile read_view_geometry_file(const std::filesystem::path& path);
/// The view alone (a video mapping in the file is checked all the same).
CArmView read_view_geometry(const std::filesystem::path& path);
/// Writes one (the projection matrix only when the view has one, the video mapping when given).
void write_view_geometry(const std::filesystem::path& path, const CArmView& view,
                         const std::optional<VideoMapping>& video_mapping = std::nullopt);

/// Reads a CT→C-arm registration: JSON {"matrix": [[4 numbers] x 4]} (row-major, mm,
/// last row 0 0 0 1). InputError names the file and the field.
Eigen::Matrix4d read_registration(const std::filesystem::path& path);

}  // namespace evar::geometry
