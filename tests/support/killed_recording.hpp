#pragma once
// A recorder killed with SIGKILL in the middle of a recording, as the OOM killer, a crash or
// `kill -9` would end it: a child process records a session replayed into it in real time
// (so the recording keeps its timing), waits until every frame is in its journal, and kills
// itself at once, before the periodic flush (C-arm rows and report, about once a second)
// could add anything. The recording directory is left as such a recorder leaves it: frames,
// journal, perhaps a report, and no session.json.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "evar/session/session_recorder.hpp"
#include "evar/session/session_replay.hpp"

namespace evar::test {

/// Lines in a file (0 when it cannot be read).
inline std::size_t line_count(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::size_t n = 0;
  for (std::string line; std::getline(in, line);) ++n;
  return n;
}

/// The child's wait status: killed by SIGKILL when all went as planned; exit code 3 when it
/// failed or its journal did not hold every frame within 30 s. Call it with no other thread running
/// (fork copies only the calling one).
inline int record_then_kill(const session::RecorderOptions& options, const session::Session& original) {
  const pid_t pid = ::fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    ::alarm(30);  // a hang ends the child, and the test says so
    try {
      session::SessionReplay replay(original, {1.0, 1});
      session::SessionRecorder recorder(options, replay.frames(), replay.carm());
      recorder.start();
      replay.wait();
      const auto journal = options.out / "journal";
      for (;;) {
        if (line_count(journal / "frames.csv") == original.frames.size() + 1) ::kill(::getpid(), SIGKILL);
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
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
