#include "evar/acquisition/serial_port.hpp"

#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace evar::acquisition {

namespace {

struct BaudConstant {
  int baud;
  speed_t constant;
};
constexpr BaudConstant kBauds[] = {
    {50, B50},         {75, B75},         {110, B110},       {134, B134},       {150, B150},
    {200, B200},       {300, B300},       {600, B600},       {1200, B1200},     {1800, B1800},
    {2400, B2400},     {4800, B4800},     {9600, B9600},     {19200, B19200},   {38400, B38400},
    {57600, B57600},   {115200, B115200}, {230400, B230400}, {460800, B460800}, {500000, B500000},
    {576000, B576000}, {921600, B921600}, {1000000, B1000000}, {1152000, B1152000},
    {1500000, B1500000}, {2000000, B2000000}, {2500000, B2500000}, {3000000, B3000000},
    {3500000, B3500000}, {4000000, B4000000},
};

speed_t baud_constant(int baud) {
  for (const auto& b : kBauds)
    if (b.baud == baud) return b.constant;
  throw std::invalid_argument("serial: unsupported baud rate " + std::to_string(baud));
}

[[noreturn]] void fail(const std::string& path, const char* call) {
  throw std::runtime_error("serial port " + path + ": " + call + " failed: " + std::strerror(errno));
}

}  // namespace

Parity parse_parity(const std::string& text) {
  if (text == "none") return Parity::None;
  if (text == "even") return Parity::Even;
  if (text == "odd") return Parity::Odd;
  throw std::invalid_argument("serial: parity '" + text + "' (expected none, even or odd)");
}

const char* to_string(Parity parity) {
  switch (parity) {
    case Parity::None: return "none";
    case Parity::Even: return "even";
    case Parity::Odd: return "odd";
  }
  return "?";
}

bool is_supported_baud(int baud) {
  for (const auto& b : kBauds)
    if (b.baud == baud) return true;
  return false;
}

void check_settings(const SerialSettings& settings) {
  (void)baud_constant(settings.baud);
  if (settings.stop_bits != 1 && settings.stop_bits != 2)
    throw std::invalid_argument("serial: stop bits must be 1 or 2 (got " + std::to_string(settings.stop_bits) + ")");
}

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
