#pragma once
// What a running live node showed and logged, for the node-level fault tests: every
// composited frame's model, held mark, roadmap and status block, readable and waitable
// while the node runs; and the node's log lines captured as text.
#include <spdlog/sinks/ostream_sink.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "evar/node/live_node.hpp"
#include "evar/node/logging.hpp"
#include "support/stream_log.hpp"

namespace evar::test {

// What the screen showed, frame by frame, readable while the node runs.
class ScreenLog final : public node::OutputSink {
 public:
  struct Shown {
    std::uint64_t version = 0;
    bool held = false;
    bool roadmap = false;
    overlay::StatusBlock status;
  };
  std::string name() const override { return "screen log"; }
  void write(const node::ComposedFrame& f) override {
    log.record([&] {
      frames.push_back({f.model ? f.model->version : 0, f.held, f.roadmap != overlay::RoadmapShown::None, f.status});
    });
  }
  static bool alert(const Shown& f, const std::string& text) {
    return std::any_of(f.status.alerts.begin(), f.status.alerts.end(),
                       [&](const std::string& a) { return a.find(text) != std::string::npos; });
  }
  /// The frame says the C-arm link is down (its state, not its news: a notice of bad
  /// frames may stay up a while after the link is back).
  static bool carm_link_down(const Shown& f) {
    return alert(f, "C-arm link stalled") || alert(f, "C-arm link disconnected") || alert(f, "C-arm link connecting");
  }
  static bool line(const Shown& f, const std::string& text) {
    return std::any_of(f.status.lines.begin(), f.status.lines.end(),
                       [&](const std::string& l) { return l.find(text) != std::string::npos; });
  }
  /// Waits until a frame from `from` on satisfies `what`; its index, or frames.size() after `limit`.
  std::size_t wait_for(std::size_t from, const std::function<bool(const Shown&)>& what, std::chrono::seconds limit) {
    std::size_t found = 0;
    const bool ok = log.wait(
        [&] {
          for (std::size_t i = from; i < frames.size(); ++i)
            if (what(frames[i])) return found = i, true;
          return false;
        },
        limit);
    std::lock_guard lock(log.mutex);
    return ok ? found : frames.size();
  }
  /// Waits until at least `n` frames were shown; false after `limit`.
  bool wait_until_shown(std::size_t n, std::chrono::seconds limit) {
    return log.wait([&] { return frames.size() >= n; }, limit);
  }
  std::size_t size() {
    std::lock_guard lock(log.mutex);
    return frames.size();
  }
  /// A copy of frame i (taken under the mutex, so while the node runs).
  Shown frame(std::size_t i) {
    std::lock_guard lock(log.mutex);
    return frames.at(i);
  }

  StreamLog log;  // its mutex guards frames
  std::vector<Shown> frames;
};

/// The node's log lines, as text, from construction to destruction.
class LogCapture {
 public:
  LogCapture() : sink_(std::make_shared<spdlog::sinks::ostream_sink_mt>(text_)) { node::log().sinks().push_back(sink_); }
  ~LogCapture() {
    auto& sinks = node::log().sinks();
    sinks.erase(std::remove(sinks.begin(), sinks.end(), sink_), sinks.end());
  }
  LogCapture(const LogCapture&) = delete;
  LogCapture& operator=(const LogCapture&) = delete;
  /// What was logged so far. Read it once the node has stopped: its threads log into it.
  std::string text() {
    node::log().flush();
    return text_.str();
  }

 private:
  std::ostringstream text_;
  std::shared_ptr<spdlog::sinks::ostream_sink_mt> sink_;
};

/// Times `what` occurs in `text`.
inline std::size_t count_of(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

}  // namespace evar::test
