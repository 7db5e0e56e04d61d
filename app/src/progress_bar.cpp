#include "progress_bar.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdio>

namespace evar::app {

std::string progress_text(std::size_t done, std::size_t total, double seconds, const std::string& what, int width) {
  const double f = total > 0 ? std::min(1.0, static_cast<double>(done) / static_cast<double>(total)) : 1.0;
  const int filled = static_cast<int>(std::lround(f * width));
  std::string bar(static_cast<std::size_t>(width) + 2, '.');
  bar.front() = '[';
  bar.back() = ']';
  for (int k = 0; k < filled; ++k) bar[static_cast<std::size_t>(k) + 1] = '#';
  char tail[128];
  const double rate = seconds > 0.0 ? static_cast<double>(done) / seconds : 0.0;
  if (done < total && rate > 0.0)
    std::snprintf(tail, sizeof tail, " %zu/%zu %s  %.1f/s  ETA %.0f s", done, total, what.c_str(), rate,
                  static_cast<double>(total - done) / rate);
  else
    std::snprintf(tail, sizeof tail, " %zu/%zu %s  %.1f/s", done, total, what.c_str(), rate);
  bar += tail;
  return bar;
}

ProgressBar::ProgressBar(std::string what, bool enabled)
    : what_(std::move(what)), enabled_(enabled), terminal_(::isatty(STDERR_FILENO) == 1),
      start_(std::chrono::steady_clock::now()), last_draw_(start_) {}

ProgressBar::~ProgressBar() { finish(); }

void ProgressBar::update(std::size_t done, std::size_t total) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  const double seconds = std::chrono::duration<double>(now - start_).count();
  if (terminal_) {
    if (done < total && now - last_draw_ < std::chrono::milliseconds(100)) return;
    last_draw_ = now;
    std::fprintf(stderr, "\r%s\033[K", progress_text(done, total, seconds, what_).c_str());
    drawn_ = true;
  } else {
    const int tenth = total > 0 ? static_cast<int>(10 * done / total) : 10;
    if (tenth == last_tenth_) return;
    last_tenth_ = tenth;
    std::fprintf(stderr, "%s\n", progress_text(done, total, seconds, what_).c_str());
  }
  std::fflush(stderr);
}

void ProgressBar::finish() {
  if (drawn_) std::fprintf(stderr, "\n");
  drawn_ = false;
}

StatusLine::StatusLine() : terminal_(::isatty(STDERR_FILENO) == 1), last_print_(std::chrono::steady_clock::now()) {}

StatusLine::~StatusLine() { finish(); }

std::optional<double> StatusLine::due() const {
  const double since = std::chrono::duration<double>(std::chrono::steady_clock::now() - last_print_).count();
  if (since < (terminal_ ? 1.0 : 10.0)) return std::nullopt;
  return since;
}

void StatusLine::print(const std::string& text) {
  std::fprintf(stderr, terminal_ ? "\r%s   " : "%s\n", text.c_str());
  drawn_ = terminal_;
  last_print_ = std::chrono::steady_clock::now();
}

void StatusLine::finish() {
  if (drawn_) std::fprintf(stderr, "\n");
  drawn_ = false;
}

}  // namespace evar::app
