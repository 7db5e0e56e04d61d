#pragma once
// Whether a session's frames fit in memory for `--preload` (session::ReplayOptions::preload).
#include "evar/session/session.hpp"

namespace evar::app {

/// Logs what preloading takes; throws std::runtime_error naming the sizes when it would
/// take more than half the machine's memory.
void check_preload_memory(const session::Session& session);

}  // namespace evar::app
