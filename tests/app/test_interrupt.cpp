// SIGTERM (`systemctl stop`, `kill`) and SIGHUP (the terminal closed) ended `evarnode record`
// on the spot, with nothing of the recording written but its PNGs, and `evarnode run` without
// its report; only Ctrl-C (SIGINT) asked them to finish cleanly. All three do now.
#include <gtest/gtest.h>

#include <atomic>
#include <csignal>
#include <cstring>

#include "interrupt.hpp"

namespace {

std::atomic<int> reached_previous_handler{0};
void previous_handler(int signal) { reached_previous_handler = signal; }

TEST(InterruptGuard, SigintSigtermAndSighupAskToFinishAndThePreviousHandlersComeBack) {
  for (const int signal : {SIGINT, SIGTERM, SIGHUP}) {
    // Had the guard not caught the signal, this handler would have (instead of the default
    // action ending the test program).
    const auto before = std::signal(signal, &previous_handler);
    reached_previous_handler = 0;
    {
      const evar::app::InterruptGuard guard;
      EXPECT_FALSE(guard.interrupted());
      std::raise(signal);
      EXPECT_TRUE(guard.interrupted()) << ::strsignal(signal);
      EXPECT_EQ(guard.signal_received(), signal);
      EXPECT_EQ(reached_previous_handler.load(), 0) << ::strsignal(signal);
    }
    std::raise(signal);  // the guard is gone: the handler before it has the signal again
    EXPECT_EQ(reached_previous_handler.load(), signal) << ::strsignal(signal);
    std::signal(signal, before);
  }
  const evar::app::InterruptGuard fresh;  // each guard starts uninterrupted
  EXPECT_FALSE(fresh.interrupted());
}

// `nohup evarnode record …` ignores SIGHUP so the recording outlives its terminal; the
// guard must leave an ignored signal ignored (the first version of it took SIGHUP over, and
// a closed terminal ended a nohup'd recording).
TEST(InterruptGuard, ASignalSetToBeIgnoredStaysIgnored) {
  const auto before = std::signal(SIGHUP, SIG_IGN);
  {
    const evar::app::InterruptGuard guard;
    std::raise(SIGHUP);
    EXPECT_FALSE(guard.interrupted());
  }
  EXPECT_EQ(std::signal(SIGHUP, before), SIG_IGN);  // and still ignored after it
}

}  // namespace
