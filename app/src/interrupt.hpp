#pragma once
// A request to finish cleanly (long replays, recordings, the node): while an InterruptGuard
// lives, SIGINT (Ctrl-C), SIGTERM (`systemctl stop`, `kill`) and SIGHUP (the terminal
// closed) set a flag the command polls, so it stops its sources and writes its files and
// report instead of dying with them half written. The previous handlers come back when it
// goes.
#include <array>
#include <atomic>
#include <csignal>

namespace evar::app {

class InterruptGuard {
 public:
  static constexpr std::array<int, 3> kSignals{SIGINT, SIGTERM, SIGHUP};

  InterruptGuard() {
    received() = 0;
    for (std::size_t i = 0; i < kSignals.size(); ++i) previous_[i] = std::signal(kSignals[i], &InterruptGuard::on_signal);
  }
  ~InterruptGuard() {
    for (std::size_t i = 0; i < kSignals.size(); ++i) std::signal(kSignals[i], previous_[i]);
  }
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;

  bool interrupted() const { return received() != 0; }
  /// The signal that asked to finish (0 while none has).
  int signal_received() const { return received(); }

 private:
  static std::atomic<int>& received() {
    static std::atomic<int> signal{0};  // lock-free, so a signal handler may set it
    return signal;
  }
  static void on_signal(int signal) { received() = signal; }
  std::array<void (*)(int), kSignals.size()> previous_{};
};

}  // namespace evar::app
