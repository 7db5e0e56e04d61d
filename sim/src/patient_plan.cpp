#include "evar/sim/patient_plan.hpp"

#include <stdexcept>

namespace evar::sim {

std::string_view to_string(Difficulty difficulty) { return difficulty == Difficulty::Paper ? "paper" : "mild"; }

std::string_view to_string(TruthPhysics physics) { return physics == TruthPhysics::Conforming ? "conforming" : "beam"; }

Difficulty parse_difficulty(std::string_view text) {
  if (text == "mild") return Difficulty::Mild;
  if (text == "paper") return Difficulty::Paper;
  throw std::invalid_argument("difficulty: \"" + std::string(text) + "\" is not one of mild, paper");
}

TruthPhysics parse_truth_physics(std::string_view text) {
  if (text == "beam") return TruthPhysics::Beam;
  if (text == "conforming") return TruthPhysics::Conforming;
  throw std::invalid_argument("truth physics: \"" + std::string(text) + "\" is not one of beam, conforming");
}

}  // namespace evar::sim
