#pragma once
// Whether an ARAP energy sequence never rises. Local/global steps cannot raise the energy
// in exact arithmetic, but E = Σ w|e'|² + Σ w|e|² − 2 Σ tr(R S) is a difference of sums a
// thousand times larger than E itself near the fixed point, so its rounding there is about
// √cells · ε · 10³ ≈ 10⁻¹² of E (seen: 2.9·10⁻¹² with another BLAS's kernels). A rise of
// 10⁻¹⁰ of E is beyond any rounding of these test meshes and is a real ascent.
#include <cstddef>
#include <vector>

#include <gtest/gtest.h>

namespace evar::test {

inline ::testing::AssertionResult energy_never_rises(const std::vector<double>& energy) {
  constexpr double kRounding = 1e-10;
  for (std::size_t k = 1; k < energy.size(); ++k)
    if (energy[k] > energy[k - 1] * (1.0 + kRounding))
      return ::testing::AssertionFailure() << "the energy rose at step " << k << " of " << energy.size() - 1 << " from "
                                           << energy[k - 1] << " to " << energy[k] << " (relative "
                                           << (energy[k] - energy[k - 1]) / energy[k - 1] << ")";
  return ::testing::AssertionSuccess();
}

}  // namespace evar::test
