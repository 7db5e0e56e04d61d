#include "evar/acquisition/serial_carm_source.hpp"

#include "wake_event.hpp"

#include <poll.h>
#include <unistd.h>

#include <array>
#include <optional>
#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace evar::acquisition {

namespace {
constexpr int kPollMs = 50;  // also the resolution of stall detection
}

SerialCArmSource::SerialCArmSource(SerialLinkOptions options)
    : options_(std::move(options)), receiver_("serial " + options_.path, options_.stale_after) {
  if (options_.path.empty()) throw std::invalid_argument("serial C-arm link: no device path");
  // Checked here, not only when the link thread opens the port: there a bad setting
  // would read as "device not there" and be retried forever.
  check_settings(options_.settings);
  wake_ = std::make_unique<WakeEvent>("serial C-arm link");
}

SerialCArmSource::~SerialCArmSource() {
  stop();
}

void SerialCArmSource::start(StateCallback on_state, StreamCallback on_stream, NoticeCallback on_notice) {
  if (thread_.joinable()) throw std::logic_error("serial C-arm link: already started");
  receiver_.set_callbacks(std::move(on_state), std::move(on_stream), std::move(on_notice));
  stop_ = false;
  wake_->clear();
  thread_ = std::thread([this] { run(); });
}

void SerialCArmSource::stop() {
  if (!thread_.joinable()) return;
  stop_ = true;
  wake_->signal();
  thread_.join();  // the thread reported Stopped as its last word
}

StreamState SerialCArmSource::state() const { return receiver_.state(); }

std::string SerialCArmSource::description() const {
  const auto& s = options_.settings;
  return "C-arm link on serial " + options_.path + " (" + std::to_string(s.baud) + " baud, parity " +
         to_string(s.parity) + ", " + std::to_string(s.stop_bits) + " stop bit" + (s.stop_bits == 2 ? "s" : "") + ")";
}

CArmLinkStatistics SerialCArmSource::statistics() const { return receiver_.statistics(); }

bool SerialCArmSource::wait_for_stop(std::chrono::milliseconds d) {
  wake_->wait(d);
  return stop_;
}

void SerialCArmSource::run() {
  std::array<std::uint8_t, 4096> buffer{};
  while (!stop_) {
    std::optional<SerialPort> port;
    try {
      port.emplace(options_.path, options_.settings);
    } catch (const std::exception& e) {
      receiver_.connecting(std::string(e.what()) + "; retrying every " +
                           std::to_string(options_.reconnect_interval.count()) + " ms");
      if (wait_for_stop(options_.reconnect_interval)) break;
      continue;
    }
    receiver_.connected();
    std::string lost;  // why the port went away, empty while it is up
    while (!stop_ && lost.empty()) {
      std::array<pollfd, 2> p{{{port->fd(), POLLIN, 0}, {wake_->fd(), POLLIN, 0}}};
      const int r = ::poll(p.data(), p.size(), kPollMs);
      if (r < 0 && errno != EINTR) lost = std::string("poll: ") + std::strerror(errno);
      if (r > 0 && (p[0].revents & (POLLIN | POLLHUP | POLLERR | POLLNVAL))) {
        // Read first even on hangup, so the last bytes before it are not lost.
        for (;;) {
          const ssize_t n = ::read(port->fd(), buffer.data(), buffer.size());
          if (n > 0) {
            receiver_.received(std::span(buffer.data(), static_cast<std::size_t>(n)), CArmLinkReceiver::Clock::now());
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
      receiver_.tick(CArmLinkReceiver::Clock::now());
    }
    if (!lost.empty()) {
      // Closed before the wait: a USB-serial adapter plugged back in while its old node is
      // still open comes back under another name (ttyUSB1 for ttyUSB0).
      port.reset();
      receiver_.disconnected("serial " + options_.path + " lost (" + lost + "); reconnecting");
      if (wait_for_stop(options_.reconnect_interval)) break;
    }
  }
  receiver_.stopped();
}

}  // namespace evar::acquisition
