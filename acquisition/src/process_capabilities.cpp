#include "evar/acquisition/process_capabilities.hpp"

#include <charconv>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>

namespace evar::acquisition {

std::optional<bool> effective_capability_in_status(std::string_view status_text, int capability) {
  if (capability < 0 || capability > 63) return std::nullopt;
  constexpr std::string_view key = "CapEff:";
  std::size_t at = 0;
  while (at < status_text.size()) {
    const std::size_t end = std::min(status_text.find('\n', at), status_text.size());
    std::string_view line = status_text.substr(at, end - at);
    at = end + 1;
    if (!line.starts_with(key)) continue;
    line.remove_prefix(key.size());
    while (!line.empty() && (line.front() == ' ' || line.front() == '\t')) line.remove_prefix(1);
    std::uint64_t mask = 0;
    const auto [ptr, ec] = std::from_chars(line.data(), line.data() + line.size(), mask, 16);
    if (ec != std::errc{} || ptr == line.data() || (ptr != line.data() + line.size() && *ptr != ' ')) return std::nullopt;
    return ((mask >> capability) & 1u) != 0;
  }
  return std::nullopt;
}

bool has_effective_capability(int capability) {
  std::ifstream in("/proc/self/status");
  std::ostringstream text;
  text << in.rdbuf();
  return effective_capability_in_status(text.str(), capability).value_or(false);
}

}  // namespace evar::acquisition
