#include "serial_port.hpp"

#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace evar::acquisition {

namespace {

[[noreturn]] void fail(const std::string& path, const char* call) {
  throw std::runtime_error("serial port " + path + ": " + call + " failed: " + std::strerror(errno));
}

}  // namespace

SerialPort::SerialPort(const std::string& path, const SerialSettings& settings) {
  check_settings(settings);
  const speed_t speed = baud_constant(settings.baud);
  // O_NOCTTY: a C-arm link must never become the node's controlling terminal.
  fd_.reset(::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC));
  if (!fd_) fail(path, "open");
  // On a throw below the descriptor closes with fd_ (after the message has read errno).
  const int fd = fd_.get();
  termios tio{};
  if (::tcgetattr(fd, &tio) != 0) fail(path, "tcgetattr (not a terminal?)");
  ::cfmakeraw(&tio);
  tio.c_cflag |= CLOCAL | CREAD;
  tio.c_cflag &= ~(CRTSCTS | CSTOPB | PARENB | PARODD);
  if (settings.stop_bits == 2) tio.c_cflag |= CSTOPB;
  if (settings.parity != Parity::None) tio.c_cflag |= PARENB;
  if (settings.parity == Parity::Odd) tio.c_cflag |= PARODD;
  // Parity errors arrive as corrupted bytes; the protocol's CRC rejects them.
  tio.c_iflag &= ~(IXON | IXOFF | IXANY | INPCK);
  tio.c_cc[VMIN] = 0;
  tio.c_cc[VTIME] = 0;
  if (::cfsetispeed(&tio, speed) != 0 || ::cfsetospeed(&tio, speed) != 0 || ::tcsetattr(fd, TCSANOW, &tio) != 0)
    fail(path, "tcsetattr");
  // tcsetattr succeeds when any setting took: read back what the driver accepted.
  termios got{};
  if (::tcgetattr(fd, &got) != 0 || ::cfgetospeed(&got) != speed ||
      (got.c_cflag & (CSTOPB | PARENB | PARODD | CSIZE)) != (tio.c_cflag & (CSTOPB | PARENB | PARODD | CSIZE))) {
    throw std::runtime_error("serial port " + path + ": the driver refused " + std::to_string(settings.baud) +
                             " baud, parity " + to_string(settings.parity) + ", " +
                             std::to_string(settings.stop_bits) + " stop bit(s)");
  }
  // Bytes queued before we listened are old geometry: a late reader must not take them as new.
  ::tcflush(fd, TCIFLUSH);
}

SerialPort::~SerialPort() = default;

}  // namespace evar::acquisition
