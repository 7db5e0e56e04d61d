#pragma once
// Durations as the reports print them: milliseconds of the steady clock, as a double.
#include <chrono>

namespace evar::base {

/// Milliseconds from `t0` to now on the steady clock.
inline double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace evar::base
