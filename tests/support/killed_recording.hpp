#pragma once
// A recorder killed with SIGKILL in the middle of a recording, as the OOM killer, a crash or
// `kill -9` would end it: a child process records a session replayed into it in real time
// (so the recording keeps its timing), waits until
// every frame and C-arm state is in its journal and the periodic report is written, and
// kills itself. The recording directory is left as such a recorder leaves it: frames,
// journal, report, and no session.json.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "evar/sim/session_recorder.hpp"
#include "evar/sim/session_replay.hpp"

namespace evar::test {

/// Lines in a file (0 when it cannot be read).
inline std::size_t line_count(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::size_t n = 0;
  for (std::string line; std::getline(in, line);) ++n;
  return n;
}

/// The child's wait status: killed by SIGKILL when all went as planned; exit code 3 when it
/// failed or its journal was not complete within 30 s. Call it with no other thread running
/// (fork copies only the calling one).
inline int record_then_kill(const sim::RecorderOptions& options, const sim::Session& original) {
  const pid_t pid = ::fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    ::alarm(30);  // a hang ends the child, and the test says so
    try {
      sim::SessionReplay replay(original, {1.0, 1});
      sim::SessionRecorder recorder(options, replay.frames(), replay.carm());
      recorder.start();
      replay.wait();
      const auto journal = options.out / "journal";
      for (;;) {  // the C-arm rows and the report reach the disk about once a second
        const bool complete = line_count(journal / "frames.csv") == original.frames.size() + 1 &&
                              line_count(journal / "carm.csv") == original.carm.size() + 1 &&
                              std::filesystem::exists(options.out / "record_report.json");
        if (complete) ::kill(::getpid(), SIGKILL);
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
    } catch (...) {
    }
    ::_exit(3);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return status;
}

}  // namespace evar::test
