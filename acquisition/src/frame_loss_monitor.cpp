#include "evar/acquisition/frame_loss_monitor.hpp"

#include <stdexcept>

namespace evar::acquisition {

FrameLossMonitor::FrameLossMonitor(FrameLossOptions options) : options_(options) {
  if (options_.window <= std::chrono::milliseconds::zero())
    throw std::invalid_argument("frame loss monitor: the window must be positive");
  if (!(options_.clear_fraction >= 0.0 && options_.clear_fraction < options_.raise_fraction &&
        options_.raise_fraction <= 1.0))
    throw std::invalid_argument("frame loss monitor: need 0 <= clear fraction < raise fraction <= 1");
}

std::optional<FrameLossMonitor::Change> FrameLossMonitor::sample(Clock::time_point now, const SequenceStats& counts) {
  if (!history_.empty() && (counts.received < history_.back().received || counts.dropped < history_.back().dropped))
    history_.clear();
  history_.push_back({now, counts.received, counts.dropped});
  // Keep one sample at or before the window's start as its baseline.
  const Clock::time_point start = now - options_.window;
  while (history_.size() >= 2 && history_[1].at <= start) history_.pop_front();
  const Sample& first = history_.front();
  const bool whole_window = first.at <= start;
  Change c;
  c.lost = counts.dropped - first.dropped;
  c.expected = c.lost + (counts.received - first.received);
  c.span = std::chrono::duration_cast<std::chrono::milliseconds>(now - first.at);
  if (!losing_) {
    if (c.expected < options_.min_frames || c.fraction() < options_.raise_fraction) return std::nullopt;
    losing_ = true;
    c.losing = true;
    return c;
  }
  if (!whole_window || c.expected == 0 || c.fraction() > options_.clear_fraction) return std::nullopt;
  losing_ = false;
  c.losing = false;
  return c;
}

}  // namespace evar::acquisition
