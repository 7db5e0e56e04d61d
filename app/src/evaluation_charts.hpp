#pragma once
// The charts of `evarnode eval`, drawn with PLplot (the plotting library of the field's
// older tools, maintained in Debian): per_case.png, each session's internal iliac ostium of
// the iliac carrying the device before and after adaptation as paired bars, and
// distribution.png, the distribution of those distances, initial against adapted; each
// with one panel per simulated physics and difficulty and the paper's means as reference
// lines.
#include <filesystem>
#include <vector>

#include "session_evaluation.hpp"

namespace evar::app {

/// Writes `path` (PNG). std::runtime_error naming the file when it cannot be written.
void write_per_case_chart(const std::filesystem::path& path, const std::vector<CaseEvaluation>& cases);
void write_distribution_chart(const std::filesystem::path& path, const std::vector<CaseEvaluation>& cases);

}  // namespace evar::app
