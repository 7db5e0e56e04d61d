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

#include "evar/acquisition/carm_geometry_source.hpp"
#include "evar/acquisition/stream_state.hpp"

namespace evar::test {

class StreamLog {
 public:
  void on_stream(acquisition::StreamState s, const std::string& reason) {
    record([&] { streams.emplace_back(s, reason); });
  }
  /// A C-arm link's notice: news that changed no state.
  void on_notice(const acquisition::LinkNotice& notice) {
    record([&] { notices.push_back(notice); });
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
  /// A state change whose reason contains every one of `parts` (and, if given, in state `s`).
  bool said(std::initializer_list<const char*> parts, const acquisition::StreamState* s = nullptr) const {
    for (const auto& [state, reason] : streams)
      if ((!s || state == *s) && contains_all(reason, parts)) return true;
    return false;
  }
  /// A notice that contains every one of `parts`.
  bool noticed(std::initializer_list<const char*> parts) const {
    for (const acquisition::LinkNotice& n : notices)
      if (contains_all(n.text, parts)) return true;
    return false;
  }

  std::mutex mutex;
  std::condition_variable cv;
  std::vector<std::pair<acquisition::StreamState, std::string>> streams;
  std::vector<acquisition::LinkNotice> notices;

 private:
  static bool contains_all(const std::string& text, std::initializer_list<const char*> parts) {
    for (const char* p : parts)
      if (text.find(p) == std::string::npos) return false;
    return true;
  }
};

}  // namespace evar::test
