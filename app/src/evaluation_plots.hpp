#pragma once
// The pictures of `evarnode eval`: the charts per_case.png and distribution.png
// (evaluation_charts.hpp) and snapshots/<session>.png (the last evaluated frame with both
// roadmaps and the true ostia as white crosses).
#include <filesystem>
#include <vector>

#include "session_evaluation.hpp"

namespace evar::app {

/// Writes the pictures into `directory`. std::runtime_error naming a file that cannot be written.
void write_evaluation_plots(const std::filesystem::path& directory, const std::vector<CaseEvaluation>& cases);

}  // namespace evar::app
