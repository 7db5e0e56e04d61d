#pragma once
// A serial port opened with termios in raw mode (8 data bits, no flow control, no echo,
// non-blocking), owned by RAII. Works on real UARTs, USB-serial adapters and pseudo-terminals.
#include <string>

#include "evar/base/unique_fd.hpp"

namespace evar::acquisition {

enum class Parity { None, Even, Odd };

struct SerialSettings {
  int baud = 115200;
  Parity parity = Parity::None;
  int stop_bits = 1;  ///< 1 or 2
};

/// "none" | "even" | "odd"; throws std::invalid_argument naming the value otherwise.
Parity parse_parity(const std::string& text);
const char* to_string(Parity parity);
/// True for the rates termios has a constant for (50 … 4000000).
bool is_supported_baud(int baud);
/// std::invalid_argument naming the setting when the port could never be opened with
/// them (unsupported baud rate, stop bits other than 1 or 2).
void check_settings(const SerialSettings& settings);

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
