#pragma once
// What is wrong right now, as the screen shows it: alerts by key, each either a condition
// (it stays until cleared) or a passing event (it clears itself after a hold). The log
// hears of an alert when its text changes or when it comes back after expiring, and of
// its end when it is cleared. Safe to use from every thread of the node.
#include <chrono>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace evar::node {

class AlertBoard {
 public:
  using Clock = std::chrono::steady_clock;

  /// hold: the alert clears itself after this long; none: it stays until clear().
  void set(const std::string& key, const std::string& text, std::optional<std::chrono::milliseconds> hold);
  /// Ends the alert under `key`, if any, and logs that it was resolved.
  void clear(const std::string& key);
  /// The texts of the alerts in force, oldest first, without the one under `except`;
  /// expired ones are dropped.
  std::vector<std::string> current(std::string_view except = {});

 private:
  struct Alert {
    std::string text;
    Clock::time_point until;  // max() = until cleared
  };
  std::mutex mutex_;
  std::vector<std::pair<std::string, Alert>> alerts_;
};

}  // namespace evar::node
