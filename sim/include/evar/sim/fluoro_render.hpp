#pragma once
// Synthetic uncontrasted fluoroscopy frames of known wires, for testing device
// segmentation and two-view reconstruction against ground truth.
//
// Physics, per detector pixel: transmitted photons N = N0·exp(−(A_anatomy + μ_wire·L_wire)),
// with L_wire the chord of the ray through the wire (a cylinder of the given diameter,
// oblique rays included), supersampled 4x4 near the wire for partial pixels; quantum noise
// (Poisson) plus electronic noise; a linear detector, dark = attenuating. The anatomy is a
// 2D line-integral map: soft tissue, a spine with vertebrae, iliac wings and femoral heads,
// so the background has bright and dark regions and strong bony edges.
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/polyline.hpp"

namespace evar::sim {

struct FluoroOptions {
  double wire_diameter_mm = 0.89;    ///< 0.035" guidewire
  double wire_mu_per_mm = 0.9;       ///< linear attenuation of the wire (stainless steel at 60–70 keV ≈ 1 /mm)
  double photons_per_pixel = 3000;   ///< unattenuated quanta per pixel (dose); lower = noisier
  double electronic_noise = 3.0;     ///< detector read noise, in quanta (standard deviation)
  int bits = 12;                     ///< output depth (CV_16UC1 holding 0 … 2^bits − 1)
  bool anatomy = true;               ///< spine, pelvis, soft tissue (else a flat field)
  double anatomy_scale = 1.0;        ///< multiplies the anatomy's line integrals
  int collimation_px = 0;            ///< lead shutters covering this many pixels on each side
  std::uint64_t seed = 1;
};

struct FluoroFrame {
  cv::Mat image;                                  ///< CV_16UC1
  std::vector<std::vector<Eigen::Vector2d>> truth;  ///< each wire's projected centreline (px), in order
};

/// A guidewire up the right iliac into an aneurysm sac centred on the isocenter (C-arm
/// world mm), tip first, bending in depth as well as sideways; `shift_x_mm` moves it to
/// the patient's left. The test and benchmark wire.
geometry::Polyline iliac_guidewire(double shift_x_mm = 0.0);

/// Renders the wires (3D polylines, world mm) as seen through projection P on a detector
/// of view.detector_cols x view.detector_rows pixels of view's spacing.
FluoroFrame render_fluoro(const geometry::ProjectionMatrix& P, const geometry::CArmView& view,
                          const std::vector<geometry::Polyline>& wires, const FluoroOptions& options = {});

}  // namespace evar::sim
