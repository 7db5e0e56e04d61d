#include "evar/acquisition/serial_carm_source.hpp"

#include <poll.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <thread>

#include "carm_link_receiver.hpp"
#include "serial_port.hpp"
#include "wake_event.hpp"

namespace evar::acquisition {

namespace {
constexpr int kPollMs = 50;  // also the resolution of stall detection
}

struct SerialCArmSource::Impl {
  SerialLinkOptions options;
  CArmLinkReceiver receiver;
  WakeEvent wake{"serial C-arm link"};  // stop() wakes the thread's poll
  std::atomic<bool> stop{false};
  std::thread thread;

  explicit Impl(SerialLinkOptions o) : options(std::move(o)), receiver("serial " + options.path, options.stale_after) {}
  bool wait_for_stop(std::chrono::milliseconds d);  ///< true when stop was asked
  void run();
};

SerialCArmSource::SerialCArmSource(SerialLinkOptions options) {
  if (options.path.empty()) throw std::invalid_argument("serial C-arm link: no device path");
  // Checked here, not only when the link thread opens the port: there a bad setting
  // would read as "device not there" and be retried forever.
  check_settings(options.settings);
  impl_ = std::make_unique<Impl>(std::move(options));
}

SerialCArmSource::~SerialCArmSource() {
  stop();
}

void SerialCArmSource::start(StateCallback on_state, StreamCallback on_stream, NoticeCallback on_notice) {
  Impl& m = *impl_;
  if (m.thread.joinable()) throw std::logic_error("serial C-arm link: already started");
  m.receiver.set_callbacks(std::move(on_state), std::move(on_stream), std::move(on_notice));
  m.stop = false;
  m.wake.clear();
  m.thread = std::thread([&m] { m.run(); });
}

void SerialCArmSource::stop() {
  Impl& m = *impl_;
  if (!m.thread.joinable()) return;
  m.stop = true;
  m.wake.signal();
  m.thread.join();  // the thread reported Stopped as its last word
}

StreamState SerialCArmSource::state() const { return impl_->receiver.state(); }

std::string SerialCArmSource::description() const {
  const auto& s = impl_->options.settings;
  return "C-arm link on serial " + impl_->options.path + " (" + std::to_string(s.baud) + " baud, parity " +
         to_string(s.parity) + ", " + std::to_string(s.stop_bits) + " stop bit" + (s.stop_bits == 2 ? "s" : "") + ")";
}

CArmLinkStatistics SerialCArmSource::statistics() const { return impl_->receiver.statistics(); }

bool SerialCArmSource::Impl::wait_for_stop(std::chrono::milliseconds d) {
  wake.wait(d);
  return stop;
}

void SerialCArmSource::Impl::run() {
  std::array<std::uint8_t, 4096> buffer{};
  while (!stop) {
    std::optional<SerialPort> port;
    try {
      port.emplace(options.path, options.settings);
    } catch (const std::exception& e) {
      receiver.connecting(std::string(e.what()) + "; retrying every " +
                           std::to_string(options.reconnect_interval.count()) + " ms");
      if (wait_for_stop(options.reconnect_interval)) break;
      continue;
    }
    receiver.connected();
    std::string lost;  // why the port went away, empty while it is up
    while (!stop && lost.empty()) {
      std::array<pollfd, 2> p{{{port->fd(), POLLIN, 0}, {wake.fd(), POLLIN, 0}}};
      const int r = ::poll(p.data(), p.size(), kPollMs);
      if (r < 0 && errno != EINTR) lost = std::string("poll: ") + std::strerror(errno);
      if (r > 0 && (p[0].revents & (POLLIN | POLLHUP | POLLERR | POLLNVAL))) {
        // Read first even on hangup, so the last bytes before it are not lost.
        for (;;) {
          const ssize_t n = ::read(port->fd(), buffer.data(), buffer.size());
          if (n > 0) {
            receiver.received(std::span(buffer.data(), static_cast<std::size_t>(n)), CArmLinkReceiver::Clock::now());
            continue;
          }
          if (n < 0 && errno == EINTR) continue;
          // A raw tty with VMIN = VTIME = 0 reads 0 bytes when drained: not an end of file.
          // A hangup shows as POLLHUP below, or as EIO here.
          if (n == 0 || errno == EAGAIN || errno == EWOULDBLOCK) break;
          lost = std::strerror(errno);
          break;
        }
        if (lost.empty() && (p[0].revents & (POLLHUP | POLLERR | POLLNVAL))) lost = "hangup";
      }
      receiver.tick(CArmLinkReceiver::Clock::now());
    }
    if (!lost.empty()) {
      // Closed before the wait: a USB-serial adapter plugged back in while its old node is
      // still open comes back under another name (ttyUSB1 for ttyUSB0).
      port.reset();
      receiver.disconnected("serial " + options.path + " lost (" + lost + "); reconnecting");
      if (wait_for_stop(options.reconnect_interval)) break;
    }
  }
  receiver.stopped();
}

}  // namespace evar::acquisition
