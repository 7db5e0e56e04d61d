#pragma once
// A progress bar for long jobs (simulated sessions, replays): redrawn in place on a
// terminal at most ten times a second; when stderr is not a terminal (logs, CI) a plain
// line every tenth of the way instead, so logs stay readable.
#include <chrono>
#include <cstddef>
#include <optional>
#include <string>

namespace evar::app {

class ProgressBar {
 public:
  /// `what` names the unit ("frames"); `enabled` false draws nothing.
  ProgressBar(std::string what, bool enabled);
  ~ProgressBar();
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  void update(std::size_t done, std::size_t total);
  /// Ends the bar's line (also done by the destructor).
  void finish();

 private:
  std::string what_;
  bool enabled_, terminal_, drawn_ = false;
  int last_tenth_ = -1;
  std::chrono::steady_clock::time_point start_, last_draw_;
};

/// A live status line for jobs without an end (live runs, recordings): redrawn in place
/// every second on a terminal, a plain line every ten seconds otherwise; the line is ended
/// before anything else is logged after it (finish, destructor).
class StatusLine {
 public:
  StatusLine();
  ~StatusLine();
  StatusLine(const StatusLine&) = delete;
  StatusLine& operator=(const StatusLine&) = delete;

  /// Seconds since the last print when one is due, else nothing.
  std::optional<double> due() const;
  void print(const std::string& text);
  void finish();

 private:
  bool terminal_, drawn_ = false;
  std::chrono::steady_clock::time_point last_print_;
};

/// The bar's text for `done` of `total` after `seconds`: "[#####.....]  45/190 frames  12.3/s  ETA 12 s".
std::string progress_text(std::size_t done, std::size_t total, double seconds, const std::string& what, int width = 30);

}  // namespace evar::app
