#pragma once
// The two hand-over points between the node's threads: a bounded queue that drops its
// oldest item when full (video must not wait, and must not pile up) and a latest-only slot
// (a busy consumer only ever wants the newest item). Both count what they dropped, and
// close() wakes every waiter for shutdown.
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <optional>

namespace evar::node {

template <typename T>
class BoundedQueue {
 public:
  explicit BoundedQueue(std::size_t capacity) : capacity_(capacity == 0 ? 1 : capacity) {}

  /// Adds an item; returns true when the oldest one had to be dropped for it.
  bool push(T item) {
    bool dropped = false;
    {
      std::lock_guard lock(m_);
      if (closed_) return false;
      if (items_.size() == capacity_) {
        items_.pop_front();
        ++dropped_;
        dropped = true;
      }
      items_.push_back(std::move(item));
    }
    cv_.notify_one();
    return dropped;
  }
  /// Adds an item, waiting while the queue is full (back-pressure onto a producer that can
  /// wait, such as a file replay); false once closed.
  bool push_wait(T item) {
    {
      std::unique_lock lock(m_);
      not_full_.wait(lock, [&] { return closed_ || items_.size() < capacity_; });
      if (closed_) return false;
      items_.push_back(std::move(item));
    }
    cv_.notify_one();
    return true;
  }
  /// The oldest item, waiting at most `timeout`; nullopt on timeout or once closed and empty.
  std::optional<T> pop(std::chrono::milliseconds timeout) {
    std::unique_lock lock(m_);
    cv_.wait_for(lock, timeout, [&] { return closed_ || !items_.empty(); });
    if (items_.empty()) return std::nullopt;
    T item = std::move(items_.front());
    items_.pop_front();
    not_full_.notify_one();
    return item;
  }
  /// No more pushes; pop() returns what is left, then nullopt at once.
  void close() {
    {
      std::lock_guard lock(m_);
      closed_ = true;
    }
    cv_.notify_all();
    not_full_.notify_all();
  }
  bool closed() const {
    std::lock_guard lock(m_);
    return closed_ && items_.empty();
  }
  std::size_t dropped() const {
    std::lock_guard lock(m_);
    return dropped_;
  }

 private:
  mutable std::mutex m_;
  std::condition_variable cv_, not_full_;
  std::deque<T> items_;
  std::size_t capacity_;
  std::size_t dropped_ = 0;
  bool closed_ = false;
};

template <typename T>
class LatestSlot {
 public:
  /// Puts an item; returns true when it replaced one nobody had taken (superseded).
  /// Nothing happens once closed.
  bool put(T item) {
    bool replaced = false;
    {
      std::lock_guard lock(m_);
      if (closed_) return false;
      replaced = item_.has_value();
      superseded_ += replaced ? 1 : 0;
      item_ = std::move(item);
    }
    cv_.notify_one();
    return replaced;
  }
  /// Puts an item only when none is waiting (a newer one would be replaced by it); false
  /// when one is, or once closed.
  bool put_if_empty(T item) {
    {
      std::lock_guard lock(m_);
      if (closed_ || item_.has_value()) return false;
      item_ = std::move(item);
    }
    cv_.notify_one();
    return true;
  }
  /// Waits for an item (nullopt once closed).
  std::optional<T> take() {
    std::unique_lock lock(m_);
    cv_.wait(lock, [&] { return closed_ || item_.has_value(); });
    if (closed_) return std::nullopt;
    std::optional<T> item = std::move(item_);
    item_.reset();
    return item;
  }
  /// The item if there is one, without waiting (nullopt when empty or closed).
  std::optional<T> try_take() {
    std::lock_guard lock(m_);
    if (closed_ || !item_) return std::nullopt;
    std::optional<T> item = std::move(item_);
    item_.reset();
    return item;
  }
  /// No more items; one left untaken is dropped and counted as superseded.
  void close() {
    {
      std::lock_guard lock(m_);
      closed_ = true;
      if (item_) {
        ++superseded_;
        item_.reset();
      }
    }
    cv_.notify_all();
  }
  /// Items never taken: replaced by a newer one, or left when the slot closed.
  std::size_t superseded() const {
    std::lock_guard lock(m_);
    return superseded_;
  }

 private:
  mutable std::mutex m_;
  std::condition_variable cv_;
  std::optional<T> item_;
  std::size_t superseded_ = 0;
  bool closed_ = false;
};

}  // namespace evar::node
