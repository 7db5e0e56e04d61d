#pragma once
// A second ground truth for synthetic patients, written from assumptions other than the
// beam model's (device_distortion.hpp) so that no one idea of the mechanics decides what
// the method is measured against:
//
// * The wire wins. A stiff EVAR wire (Amplatz Super Stiff to Lunderquist, 6 to 17 times the
//   flexural modulus of a plain Amplatz wire) straightens a tortuous iliac to its own
//   course: the carrier iliac's lumen centre moves onto the wire, keeping only a fraction
//   (`wire_offset_fraction`) of its preoperative offset from it, within the lumen.
// * A straightened vessel keeps its wall length. The excess length of the tortuous iliac
//   over the wire's course is taken up partly by folds (the accordion or concertina seen
//   with stiff wires; endografts in severely tortuous iliacs shorten by about 13 %) and
//   partly by sliding distally along the wire past the access (`fold_fraction` splits it);
//   in the rare vessel shorter than the wire's course through it, it is stretched to it.
//   Its branches' ostia move along the wire with the wall they sit on.
// * What holds the aorta is its visceral and renal branches: it does not move above the
//   renal level, and below it the wall gives way where the wire presses, as a string under
//   axial tension on a soft bed (arteries are stretched along their length in vivo), so a
//   push decays exponentially over `aorta_decay_mm`.
// * The other iliac follows the aortic bifurcation, the follow fading linearly to its
//   groin. The iliacs' cross-sections turn with the centerline (the beam model translates
//   them); the aorta's translate, as its aneurysm sac is a bag rather than a tube.
#include <cstdint>

#include "evar/sim/device_distortion.hpp"
#include "evar/sim/example_scene.hpp"

namespace evar::sim {

struct ConformingOptions {
  double wire_offset_fraction = 0.3;  ///< 0: the lumen centre on the wire; 1: offset kept (within the lumen)
  double fold_fraction = 0.5;         ///< share of the excess iliac length folded; the rest slides distally
  double aorta_decay_mm = 25.0;       ///< sqrt(tension / bed stiffness) of the infrarenal aorta
  double junction_blend_mm = 35.0;    ///< the carrier iliac turns from the bifurcation onto the wire over this
  double clearance_mm = 0.3;          ///< gap kept between the device surface and the wall
  int max_contact_rounds = 300;
};

/// The per-patient mechanics, from the seed (its own stream): wire_offset_fraction in
/// [0, 0.5), fold_fraction in [0, 1), aorta_decay_mm in [15, 40).
ConformingOptions draw_conforming_options(std::uint64_t seed);

/// Distorts `scene`'s vessels (closed tubes swept along their centerlines with radii_mm)
/// so they hold `scene.device` (tip first, access at the carrier iliac's distal end), by
/// the model above; the result has the same layout, vertex order and faces as
/// distort_by_device's, and the same containment check on the meshes
/// (device_points_outside). Throws std::invalid_argument for a scene without an aorta and
/// an iliac or a device of < 2 points, std::runtime_error when the aortic contact does not
/// settle.
DeviceDistortion distort_by_conforming(const ExampleScene& scene, const ConformingOptions& options = {});

/// Re-sweeps `mesh` around `centerline` along `moved` (same point count), turning each
/// cross-section with the centerline's tangent (the least rotation, interpolated between
/// points) as well as moving it (only moving it when `turn` is false): with moved ==
/// centerline the mesh comes back unchanged.
geometry::TriangleMesh resweep_turning(const geometry::TriangleMesh& mesh, const geometry::Polyline& centerline,
                                       const geometry::Polyline& moved, bool turn = true);

}  // namespace evar::sim
