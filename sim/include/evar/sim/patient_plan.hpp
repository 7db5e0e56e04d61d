#pragma once
// What kind of synthetic patient to make: how hard its anatomy, device and registration
// are (the difficulty) and which ground-truth mechanics distorts it (the truth physics).
// docs/SYNTHETIC_PATIENTS.md describes every level and physics and what each is built on.
#include <cstdint>
#include <string>
#include <string_view>

namespace evar::sim {

enum class Difficulty {
  /// Moderately tortuous iliacs, a 30-60 mm bending-length wire, and a registration
  /// without residual: the simulator as it was first calibrated.
  Mild,
  /// The seed paper's initial error: tortuous iliacs as AAA patients have them, stiff
  /// wires of the Amplatz and Lunderquist class, and a registration residual about the
  /// renal level (registration_residual.hpp).
  Paper,
};

enum class TruthPhysics {
  /// Centerline beams on an elastic foundation, pushed by contact with the rigid device;
  /// sections translate (device_distortion.hpp).
  Beam,
  /// The carrier iliac threaded on the stiff wire: it takes the wire's course, keeps its
  /// length by sliding along it or folding (accordion); the aorta is held at the renal
  /// level and gives way by contact; sections turn with the centerline
  /// (conforming_distortion.hpp).
  Conforming,
};

std::string_view to_string(Difficulty difficulty);
std::string_view to_string(TruthPhysics physics);
/// "mild" / "paper"; std::invalid_argument naming the choices for anything else.
Difficulty parse_difficulty(std::string_view text);
/// "beam" / "conforming"; std::invalid_argument naming the choices for anything else.
TruthPhysics parse_truth_physics(std::string_view text);

struct PatientPlan {
  std::uint64_t seed = 1;
  Difficulty difficulty = Difficulty::Mild;
  TruthPhysics physics = TruthPhysics::Beam;
  int aorta_vertices = 7500, iliac_vertices = 3500;
};

}  // namespace evar::sim
