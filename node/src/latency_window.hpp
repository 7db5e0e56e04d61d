#pragma once
// The most recent latencies (ms), a fixed number of them, for the node's percentiles: the
// oldest goes when a new one comes. Not synchronised: the node guards it with its counts.
#include <cstddef>
#include <deque>
#include <vector>

namespace evar::node {

class LatencyWindow {
 public:
  explicit LatencyWindow(std::size_t capacity) : capacity_(capacity) {}
  void add(double ms) {
    values_.push_back(ms);
    if (values_.size() > capacity_) values_.pop_front();
  }
  /// A copy, to be sorted (node_statistics.hpp's percentiles) outside the lock.
  std::vector<double> values() const { return {values_.begin(), values_.end()}; }

 private:
  std::size_t capacity_;
  std::deque<double> values_;
};

}  // namespace evar::node
