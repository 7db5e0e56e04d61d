#pragma once
// An analytic abdomen and pelvis in patient LPS millimetres (origin at the aortic
// bifurcation, as the synthetic patients): soft tissue as an elliptic cylinder, lumbar
// vertebrae with cortical shells and pedicles, the sacrum, iliac wings, femoral heads and
// bowel gas, each an ellipsoid (or the cylinder) of constant linear attenuation relative to
// the tissue it displaces. Line integrals are exact (ray–quadric chords), so a rotated
// C-arm sees the spine move against the vessels as it does in a patient.
#include <Eigen/Core>
#include <vector>

#include <opencv2/core.hpp>

#include "evar/geometry/triangle_mesh.hpp"

namespace evar::sim {

struct Ellipsoid {
  Eigen::Vector3d centre_mm;
  Eigen::Vector3d semi_axes_mm;  ///< along the patient axes (L, P, S)
  double mu_per_mm;              ///< attenuation added inside (negative for gas)
};

struct BodyPhantom {
  /// Soft tissue: an elliptic cylinder along z (infinite), semi-axes in x and y.
  Eigen::Vector2d body_centre_mm{0.0, 25.0};
  Eigen::Vector2d body_semi_axes_mm{165.0, 115.0};
  double tissue_mu_per_mm = 0.019;  ///< water at about 65 keV effective
  std::vector<Ellipsoid> parts;     ///< bone and gas, added to the tissue
  /// parts[pelvis_begin, pelvis_end) are the pelvis's bones (sacrum, hip bones, femoral heads).
  std::size_t pelvis_begin = 0, pelvis_end = 0;
};

/// The default phantom for a patient whose aortic bifurcation is at the origin: L1–L5
/// above it (bodies 25 mm tall, 8 mm discs) behind the aorta, the sacrum, pelvis and hips
/// below, a few gas pockets. `seed` varies gas pockets only.
BodyPhantom default_body_phantom(unsigned seed = 1);

/// The pelvis's bones as a CT bone segmentation would give them: the outer surface of each
/// of its denser-than-tissue parts, a closed ellipsoid of 642 vertices each (outward faces),
/// in the phantom's coordinates. The hollows inside the iliac wings are not surfaces of their
/// own (a segmentation of bone takes the marrow in).
geometry::TriangleMesh pelvis_mesh(const BodyPhantom& phantom);

/// Adds the phantom's line integral ∫μ dl for every pixel ray of P (detector cols x rows)
/// to `A` (CV_64F, rows x cols), the phantom placed by `patient_to_world` (world = C-arm
/// LPS), which must be rigid (a registration, as session files require). Each part is evaluated only over the pixels its bounding box
/// projects to, so a frame costs about one full pass plus the bones' footprints.
void add_line_integrals(const BodyPhantom& phantom, const Eigen::Matrix4d& patient_to_world,
                        const Eigen::Matrix<double, 3, 4>& P, cv::Mat& A);

/// Chord length (mm) of the ray origin + t·direction (unit), t >= 0, through an
/// axis-aligned ellipsoid; 0 when it misses.
double ellipsoid_chord(const Eigen::Vector3d& centre, const Eigen::Vector3d& semi_axes, const Eigen::Vector3d& origin,
                       const Eigen::Vector3d& direction);

}  // namespace evar::sim
