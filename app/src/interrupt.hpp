#pragma once
// A request to finish cleanly (long replays, recordings, the node): while an InterruptGuard
// lives, SIGINT (Ctrl-C), SIGTERM (`systemctl stop`, `kill`) and SIGHUP (the terminal
// closed) set a flag the command polls, so it stops its sources and writes its files and
// report instead of dying with them half written. The previous handlers come back when it
// goes.
#include <signal.h>

#include <array>
#include <atomic>

namespace evar::app {

class InterruptGuard {
 public:
  static constexpr std::array<int, 3> kSignals{SIGINT, SIGTERM, SIGHUP};

  /// A signal someone set to be ignored stays ignored (`nohup` ignores SIGHUP so a
  /// recording outlives its terminal; a background job's shell may ignore SIGINT).
  InterruptGuard() {
    received() = 0;
    for (std::size_t i = 0; i < kSignals.size(); ++i) {
      struct sigaction current {};
      ::sigaction(kSignals[i], nullptr, &current);
      if (current.sa_handler == SIG_IGN) continue;
      struct sigaction ours {};
      ours.sa_handler = &InterruptGuard::on_signal;
      sigemptyset(&ours.sa_mask);
      ours.sa_flags = SA_RESTART;  // system calls interrupted by it carry on; the flag is polled
      if (::sigaction(kSignals[i], &ours, &previous_[i]) == 0) installed_[i] = true;
    }
  }
  ~InterruptGuard() {
    for (std::size_t i = 0; i < kSignals.size(); ++i)
      if (installed_[i]) ::sigaction(kSignals[i], &previous_[i], nullptr);
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
  std::array<struct sigaction, kSignals.size()> previous_{};
  std::array<bool, kSignals.size()> installed_{};
};

}  // namespace evar::app
