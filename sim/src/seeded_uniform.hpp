#pragma once
// Uniform draws from std::mt19937_64 with our own 53-bit mapping to [0, 1): std::
// distributions may differ between standard libraries, so a seed would not give the same
// patient or session everywhere; these draws do.
#include <cstdint>
#include <random>

namespace evar::sim {

class SeededUniform {
 public:
  explicit SeededUniform(std::uint64_t seed) : engine_(seed) {}
  /// In [0, 1), 53 random bits.
  double unit() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  /// In [lo, hi).
  double operator()(double lo, double hi) { return lo + unit() * (hi - lo); }

 private:
  std::mt19937_64 engine_;
};

}  // namespace evar::sim
