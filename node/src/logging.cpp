#include "evar/node/logging.hpp"

#include <spdlog/sinks/stdout_color_sinks.h>

namespace evar::node {

spdlog::logger& log() {
  static const std::shared_ptr<spdlog::logger> logger = [] {
    auto l = spdlog::stderr_color_mt("evarnode");
    l->set_pattern("%H:%M:%S.%e %^%-5l%$ %v");
    l->set_level(spdlog::level::info);
    return l;
  }();
  return *logger;
}

void set_log_level(const std::string& level) { log().set_level(spdlog::level::from_str(level)); }

}  // namespace evar::node
