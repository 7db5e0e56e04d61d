#pragma once
// A serial port opened with termios in raw mode (8 data bits, no flow control, no echo,
// non-blocking), owned by RAII. Works on real UARTs, USB-serial adapters and pseudo-terminals.
#include <termios.h>

#include <string>

#include "evar/acquisition/serial_settings.hpp"
#include "evar/base/unique_fd.hpp"

namespace evar::acquisition {

/// The termios constant of a rate is_supported_baud() accepts; std::invalid_argument otherwise.
speed_t baud_constant(int baud);

class SerialPort {
 public:
  /// Opens and configures; throws std::runtime_error naming the path and the failing call.
  SerialPort(const std::string& path, const SerialSettings& settings);
  ~SerialPort();
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;

  int fd() const { return fd_.get(); }

 private:
  base::UniqueFd fd_;
};

}  // namespace evar::acquisition
