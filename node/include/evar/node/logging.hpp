#pragma once
// The one logger of the executable: human-readable lines on stderr.
#include <spdlog/spdlog.h>

namespace evar::node {

spdlog::logger& log();
/// "error", "warn", "info" (default), "debug".
void set_log_level(const std::string& level);

}  // namespace evar::node
