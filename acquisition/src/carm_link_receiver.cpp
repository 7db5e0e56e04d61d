#include "carm_link_receiver.hpp"

#include <utility>
#include <variant>
#include <vector>

namespace evar::acquisition {

CArmLinkReceiver::CArmLinkReceiver(std::string name, std::chrono::milliseconds stale_after)
    : name_(std::move(name)), stale_after_(stale_after) {}

void CArmLinkReceiver::set_callbacks(CArmGeometrySource::StateCallback on_state,
                                     CArmGeometrySource::StreamCallback on_stream,
                                     CArmGeometrySource::NoticeCallback on_notice) {
  std::lock_guard lock(mutex_);
  on_state_ = std::move(on_state);
  on_stream_ = std::move(on_stream);
  on_notice_ = std::move(on_notice);
}

// Notifications are collected under the mutex and delivered after it is released, so a
// callback may ask the source for its state or statistics. Only the transport's thread
// calls in here, which keeps them in order.
void CArmLinkReceiver::set_state(StreamState s, const std::string& reason) {
  if (s == state_ && reason == reason_) return;
  state_ = s;
  reason_ = reason;
  pending_.emplace_back(Change{s, reason});
}

void CArmLinkReceiver::deliver(std::unique_lock<std::mutex>& lock, const std::vector<CArmState>& samples) {
  std::vector<Pending> pending;
  pending.swap(pending_);
  auto on_state = on_state_;
  auto on_stream = on_stream_;
  auto on_notice = on_notice_;
  lock.unlock();
  for (const Pending& p : pending) {
    if (const auto* c = std::get_if<Change>(&p)) {
      if (on_stream) on_stream(c->state, c->reason);
    } else if (on_notice) {
      on_notice(std::get<LinkNotice>(p));
    }
  }
  for (const CArmState& s : samples)
    if (on_state) on_state(s);
}

void CArmLinkReceiver::connecting(const std::string& reason) {
  std::unique_lock lock(mutex_);
  set_state(StreamState::Connecting, reason);
  deliver(lock, {});
}

void CArmLinkReceiver::connected() {
  std::unique_lock lock(mutex_);
  ++stats_.connections;
  decoder_.reset_partial();
  decoder_.reset_sequence();
  last_sample_.reset();
  set_state(StreamState::Connecting, name_ + " open, waiting for the first geometry sample");
  deliver(lock, {});
}

void CArmLinkReceiver::received(std::span<const std::uint8_t> bytes, Clock::time_point now) {
  std::unique_lock lock(mutex_);
  std::vector<CArmState> samples;
  decoder_.feed(bytes, [&](const carm_link::Message& m) {
    if (const auto* g = std::get_if<carm_link::GeometryMessage>(&m)) {
      CArmState s = g->state;
      s.host_arrival = now;
      samples.push_back(s);
    } else {
      const auto& status = std::get<carm_link::StatusMessage>(m);
      stats_.last_status = status;
      if (status.level != carm_link::StatusLevel::Info) {
        std::string text = "C-arm " + std::string(to_string(status.level)) + ": " + status.text;
        // A status repeated within the interval is news once (a C-arm may repeat its
        // warnings every frame, several in turn): texts are remembered for one interval.
        // A peer sending ever new texts is held to kMaxStatusTexts notices per interval.
        std::erase_if(status_noticed_, [&](const auto& e) { return now - e.second >= kNoticeInterval; });
        if (!status_noticed_.contains(text)) {
          if (status_noticed_.size() < kMaxStatusTexts) {
            status_noticed_.emplace(text, now);
            pending_.emplace_back(LinkNotice{LinkNotice::Kind::CArmStatus, std::move(text)});
          } else {
            ++stats_.statuses_not_reported;
          }
        }
      }
    }
  });
  stats_.link = decoder_.stats();
  stats_.last_error = decoder_.last_error();
  report_errors(now);
  if (!samples.empty()) {
    last_sample_ = now;
    set_state(StreamState::Streaming, name_ + " streaming");
  }
  deliver(lock, samples);
}

void CArmLinkReceiver::report_errors(Clock::time_point now) {
  const std::uint64_t errors = stats_.link.errors();
  if (errors == errors_reported_ || (last_error_notice_ && now - *last_error_notice_ < kNoticeInterval)) return;
  const std::string link = "C-arm link " + name_ + ": ";
  const std::string total = " (" + std::to_string(errors) + " bad frames so far)";
  std::string text = !last_error_notice_ || errors - errors_reported_ == 1
                         ? link + decoder_.last_error() + total
                         : link + std::to_string(errors - errors_reported_) + " bad frames since the last report" +
                               total + "; the last: " + decoder_.last_error();
  pending_.emplace_back(LinkNotice{LinkNotice::Kind::BadFrames, std::move(text)});
  errors_reported_ = errors;
  last_error_notice_ = now;
}

void CArmLinkReceiver::tick(Clock::time_point now) {
  std::unique_lock lock(mutex_);
  report_errors(now);  // what a burst left unreported
  if (state_ == StreamState::Streaming && last_sample_ && now - *last_sample_ > stale_after_)
    set_state(StreamState::Stalled, name_ + ": no geometry for " + std::to_string(stale_after_.count()) + " ms");
  deliver(lock, {});
}

void CArmLinkReceiver::disconnected(const std::string& reason) {
  std::unique_lock lock(mutex_);
  ++stats_.disconnections;
  decoder_.reset_partial();
  set_state(StreamState::Disconnected, reason);
  deliver(lock, {});
}

void CArmLinkReceiver::stopped() {
  std::unique_lock lock(mutex_);
  set_state(StreamState::Stopped, name_ + " stopped");
  deliver(lock, {});
}

StreamState CArmLinkReceiver::state() const {
  std::lock_guard lock(mutex_);
  return state_;
}

CArmLinkStatistics CArmLinkReceiver::statistics() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

}  // namespace evar::acquisition
