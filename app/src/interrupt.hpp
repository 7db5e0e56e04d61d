#pragma once
// Ctrl-C as a request to finish cleanly (long replays and recordings): while an
// InterruptGuard lives, SIGINT sets a flag the command polls; the previous handler comes
// back when it goes.
#include <atomic>
#include <csignal>

namespace evar::app {

class InterruptGuard {
 public:
  InterruptGuard() : previous_(std::signal(SIGINT, &InterruptGuard::on_signal)) { flag() = false; }
  ~InterruptGuard() { std::signal(SIGINT, previous_); }
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;
  bool interrupted() const { return flag(); }

 private:
  static std::atomic<bool>& flag() {
    static std::atomic<bool> f{false};
    return f;
  }
  static void on_signal(int) { flag() = true; }
  void (*previous_)(int);
};

}  // namespace evar::app
