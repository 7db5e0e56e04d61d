#pragma once
// Fluoroscopy and DSA-like frames of a synthetic patient for any C-arm view.
//
// Per pixel ray: A = ∫μ over the body phantom + μ_iodine·(path length through the
// contrast-filled vessel meshes); expected quanta N = N0·exp(−(A − A_min))·T_wire (the
// wires' own sub-pixel shadow), A_min the body's least attenuation in the field: automatic
// exposure control gives the brightest body region N0 quanta. The detector: Poisson quanta (Gaussian above 50), a Gaussian light
// spread of the scintillator over the noisy quanta (so noise is blurred like signal),
// electronic noise, linear gain to `bits` (dark = attenuating), 16-bit storage.
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/triangle_mesh.hpp"
#include "evar/sim/body_phantom.hpp"

namespace evar::sim {

struct XRayOptions {
  double photons_per_pixel = 3000;  ///< quanta behind the least attenuating body path in the field (dose)
  double electronic_noise = 3.0;    ///< read noise, quanta (standard deviation)
  double detector_blur_px = 0.7;    ///< scintillator light spread (Gaussian sigma, px); 0 = none
  int bits = 12;                    ///< output depth (CV_16UC1 holding 0 … 2^bits − 1)
  double wire_diameter_mm = 0.89;   ///< 0.035" guidewire
  double wire_mu_per_mm = 0.9;      ///< stainless steel at 60–70 keV
  /// Iodinated contrast mixed with blood, above blood itself: about 75 mg I/ml at 60–70 keV
  /// effective (iodine ≈ 6.5 cm²/g there).
  double iodine_mu_per_mm = 0.05;
};

/// What the beam crosses, in patient (CT LPS) millimetres, and where the patient is.
struct XRayContent {
  const BodyPhantom* body = nullptr;                       ///< nullptr: air
  Eigen::Matrix4d patient_to_world = Eigen::Matrix4d::Identity();  ///< CT → C-arm (registration with the table)
  std::vector<const geometry::TriangleMesh*> contrast;     ///< closed, outward vessel meshes filled with iodine
  double contrast_fraction = 0.0;                          ///< 0 (no contrast) … 1 (full bolus)
  std::vector<geometry::Polyline> wires;                   ///< devices
};

/// The noise-free part of a frame, to be reused for every frame of a settled view.
struct XRayExpected {
  cv::Mat quanta;                                        ///< CV_64F expected quanta per pixel
  std::vector<std::vector<Eigen::Vector2d>> wire_truth;  ///< each wire's projected centreline (px)
};

/// Path length (mm) of every pixel ray of P through the union of the closed meshes
/// (vertices mapped by `patient_to_world`; overlapping vessels such as the iliacs' starts inside
/// the aorta count once), added to `L` (CV_64F, detector size). Triangles are rasterized at
/// pixel centres with a top-left rule, so shared edges count once; each gives the distance
/// at which the ray enters or leaves, and the entries and exits are swept in order.
void add_path_lengths(const std::vector<const geometry::TriangleMesh*>& meshes, const Eigen::Matrix4d& patient_to_world,
                      const geometry::ProjectionMatrix& P, cv::Mat& L);

/// The expected image of `content` through view `view` (P = projection_matrix(view)).
XRayExpected expected_xray(const geometry::CArmView& view, const XRayContent& content, const XRayOptions& options = {});

/// One detector readout of an expected image: noise from `seed`, blur, quantization.
cv::Mat detect(const cv::Mat& expected_quanta, const XRayOptions& options, std::uint64_t seed);

}  // namespace evar::sim
