#pragma once
// What a source reported from its own thread, for tests that wait on conditions, never on
// fixed sleeps. Derived logs keep their own records (samples, frames) under the same mutex
// through record().
#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "evar/acquisition/stream_state.hpp"

namespace evar::test {

class StreamLog {
 public:
  void on_stream(acquisition::StreamState s, const std::string& reason) {
    record([&] { streams.emplace_back(s, reason); });
  }
  /// Runs `change` under the log's mutex and wakes the waiters.
  void record(const std::function<void()>& change) {
    std::lock_guard lock(mutex);
    change();
    cv.notify_all();
  }
  /// Waits until `done` (evaluated under the mutex) holds; false after `limit`.
  bool wait(const std::function<bool()>& done, std::chrono::milliseconds limit = std::chrono::seconds(30)) {
    std::unique_lock lock(mutex);
    return cv.wait_for(lock, limit, done);
  }
  // The predicates below read the records: call them inside wait() or with the mutex held.
  bool saw(acquisition::StreamState s, std::size_t from = 0) const {
    for (std::size_t i = from; i < streams.size(); ++i)
      if (streams[i].first == s) return true;
    return false;
  }
  /// A notice whose reason contains every one of `parts` (and, if given, in state `s`).
  bool said(std::initializer_list<const char*> parts, const acquisition::StreamState* s = nullptr) const {
    for (const auto& [state, reason] : streams) {
      if (s && state != *s) continue;
      bool all = true;
      for (const char* p : parts) all &= reason.find(p) != std::string::npos;
      if (all) return true;
    }
    return false;
  }

  std::mutex mutex;
  std::condition_variable cv;
  std::vector<std::pair<acquisition::StreamState, std::string>> streams;
};

}  // namespace evar::test
