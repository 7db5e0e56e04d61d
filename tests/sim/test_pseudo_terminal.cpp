// The pseudo-terminal the simulator serves a C-arm link on (the adapter's side of a serial
// cable).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <vector>

#include "evar/sim/pseudo_terminal.hpp"

// A replay serving the C-arm link with no node reading it must not hang: once the pty's
// buffer is full, messages are dropped (a part-written one after at most 200 ms) and the
// writer goes on. Before the fix it blocked for good on the first part-written message
// (after about 400 messages). In a child process with an alarm, so a hang fails the test.
TEST(PseudoTerminal, AWriterNobodyReadsDropsMessagesInsteadOfHanging) {
  EXPECT_EXIT(
      {
        ::alarm(30);
        evar::sim::PseudoTerminal pty;
        const std::vector<std::uint8_t> message(48, 0x11);
        int dropped = 0;
        for (int i = 0; i < 3000; ++i)
          if (!pty.write_or_drop(message)) ++dropped;
        std::exit(dropped > 0 ? 0 : 3);
      },
      testing::ExitedWithCode(0), "");
}
