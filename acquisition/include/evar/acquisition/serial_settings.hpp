#pragma once
// How a serial C-arm link is framed on the wire: baud rate, parity, stop bits (8 data bits,
// no flow control, as every C-arm adapter we know speaks).
#include <string>

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

}  // namespace evar::acquisition
