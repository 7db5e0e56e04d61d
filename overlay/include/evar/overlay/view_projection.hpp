#pragma once
// Projections from patient LPS millimetres (x = patient Left, y = Posterior, z = Superior)
// to image pixels (u to the right, v down). Pixel (i, j) is centred at u = i, v = j, so a
// width x height image covers u in [-0.5, width - 0.5] and v in [-0.5, height - 0.5]
// (OpenCV's convention, so drawing code needs no half-pixel fix-ups).
//
// ViewProjection is the seam between the roadmap compositor and the imaging geometry:
// today the orthographic standard views of the preview picture, later a perspective C-arm
// projection (a 3x4 matrix P from calibration) as another implementation.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <limits>
#include <span>

namespace evar::overlay {

class ViewProjection {
 public:
  virtual ~ViewProjection() = default;

  /// Image position (px; u right, v down) of a patient point (LPS mm).
  virtual Eigen::Vector2d project(const Eigen::Vector3d& p_lps) const = 0;

  /// Signed distance (mm) of the point along the viewing direction; larger is farther
  /// from the viewer (towards the detector). Orthographic views measure from an arbitrary
  /// plane, so only differences matter; a perspective view measures from the source.
  virtual double depth(const Eigen::Vector3d& p_lps) const = 0;

  /// Points with depth() <= near_depth() cannot be projected (at or behind a perspective
  /// source) and are not drawn; -infinity for orthographic views.
  virtual double near_depth() const { return -std::numeric_limits<double>::infinity(); }

  /// Size (px) of the image the projection maps into.
  int width() const { return width_; }
  int height() const { return height_; }

 protected:
  /// Throws std::invalid_argument unless both sizes are positive.
  ViewProjection(int width, int height);
  // Copyable only through concrete types, so a projection cannot be sliced.
  ViewProjection(const ViewProjection&) = default;
  ViewProjection& operator=(const ViewProjection&) = default;

 private:
  int width_;
  int height_;
};

/// The two standard views of the preview picture, displayed as interventionalists read
/// them (the image as seen by a viewer standing on the detector side).
enum class StandardView {
  /// Frontal, read like an AP radiograph: the viewer faces the patient and looks
  /// posteriorly (+y). Patient Left (+x) is on the image right (so the patient's right is
  /// on the viewer's left), Superior (+z) is up.
  AP,
  /// Left lateral (like LAO 90, detector at the patient's left): the viewer looks from
  /// the patient's left towards the right (-x). Anterior (-y) is on the image LEFT,
  /// Posterior (+y) on the image right, Superior (+z) up.
  Lateral,
};

/// "AP" or "Lateral".
const char* to_string(StandardView view);

/// Image axes of a view as unit LPS vectors: `right` (+u), `down` (+v) and `forward`
/// (viewing direction, +depth); right x down = forward, like a camera frame.
struct ViewAxes {
  Eigen::Vector3d right, down, forward;
};

/// The axes of a standard view (AP: right +x, down -z, forward +y; Lateral: right +y,
/// down -z, forward -x).
ViewAxes view_axes(StandardView view);

/// Parallel projection along `axes.forward` at a fixed scale:
///   u = (width - 1) / 2 + (p - centre) . right / mm_per_pixel
///   v = (height - 1) / 2 + (p - centre) . down / mm_per_pixel
///   depth = (p - centre) . forward
class OrthographicProjection final : public ViewProjection {
 public:
  /// `axes` must be orthonormal and right-handed (right x down = forward, within 1e-9);
  /// `centre_lps` (mm) lands on the image centre; `mm_per_pixel` > 0 and finite; both
  /// sizes > 0 (px). Throws std::invalid_argument otherwise.
  OrthographicProjection(const ViewAxes& axes, const Eigen::Vector3d& centre_lps, double mm_per_pixel,
                         int width, int height);

  /// A standard view centred on `bounds_lps` (mm) at `mm_per_pixel`, width x height px.
  static OrthographicProjection fit(StandardView view, const Eigen::AlignedBox3d& bounds_lps,
                                    double mm_per_pixel, int width, int height);

  Eigen::Vector2d project(const Eigen::Vector3d& p_lps) const override;
  double depth(const Eigen::Vector3d& p_lps) const override;

  const ViewAxes& axes() const { return axes_; }
  const Eigen::Vector3d& centre_lps() const { return centre_; }
  double mm_per_pixel() const { return mm_per_pixel_; }

 private:
  ViewAxes axes_;
  Eigen::Vector3d centre_;
  double mm_per_pixel_;
};

/// Extent (mm) of `bounds_lps` along a view's image axes: (along u, along v).
Eigen::Vector2d view_extent_mm(StandardView view, const Eigen::AlignedBox3d& bounds_lps);

/// The smallest scale (mm per pixel) at which `bounds_lps` fits inside width x height px,
/// leaving `margin_px` free on every side, in each of `views`: one scale shared by all
/// panels so that sizes compare between them. A box that is a single point in every view
/// gets 1 mm per pixel. Throws std::invalid_argument for an empty box, no views, or no room inside the margins.
double fit_mm_per_pixel(const Eigen::AlignedBox3d& bounds_lps, std::span<const StandardView> views,
                        int width, int height, int margin_px);

}  // namespace evar::overlay
