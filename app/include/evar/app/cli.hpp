#pragma once
// The `evarnode` command line, as a function so tests can run it in-process.
#include <string>
#include <vector>

namespace evar::app {

/// Runs `evarnode <args...>` (args without the program name). Returns the exit code:
/// 0 success, 1 bad input or failed run (the message names the file and problem),
/// 2 bad command line.
int run_cli(const std::vector<std::string>& args);

}  // namespace evar::app
