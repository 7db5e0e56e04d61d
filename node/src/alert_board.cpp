#include "alert_board.hpp"

#include <algorithm>

#include "evar/node/logging.hpp"

namespace evar::node {

void AlertBoard::set(const std::string& key, const std::string& text, std::optional<std::chrono::milliseconds> hold) {
  const auto until = hold ? Clock::now() + *hold : Clock::time_point::max();
  bool changed = true;
  {
    std::lock_guard lock(mutex_);
    auto it = std::find_if(alerts_.begin(), alerts_.end(), [&](const auto& a) { return a.first == key; });
    if (it != alerts_.end()) {
      // One that expired unseen (no frame composed since) is news again.
      changed = it->second.text != text || it->second.until <= Clock::now();
      it->second = {text, until};
    } else {
      alerts_.push_back({key, {text, until}});
    }
  }
  if (changed) log().warn("{}", text);
}

void AlertBoard::clear(const std::string& key) {
  std::string text;
  {
    std::lock_guard lock(mutex_);
    auto it = std::find_if(alerts_.begin(), alerts_.end(), [&](const auto& a) { return a.first == key; });
    if (it == alerts_.end()) return;
    text = std::move(it->second.text);
    alerts_.erase(it);
  }
  log().info("resolved: {}", text);
}

std::vector<std::string> AlertBoard::current(std::string_view except) {
  std::lock_guard lock(mutex_);
  const auto now = Clock::now();
  std::erase_if(alerts_, [&](const auto& a) { return a.second.until <= now; });
  std::vector<std::string> out;
  for (const auto& a : alerts_)
    if (a.first != except) out.push_back(a.second.text);
  return out;
}

}  // namespace evar::node
