#include "evar/acquisition/serial_settings.hpp"

#include <termios.h>

#include <stdexcept>
#include <string>

#include "serial_port.hpp"

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

}  // namespace

speed_t baud_constant(int baud) {
  for (const auto& b : kBauds)
    if (b.baud == baud) return b.constant;
  throw std::invalid_argument("serial: unsupported baud rate " + std::to_string(baud));
}

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

}  // namespace evar::acquisition
