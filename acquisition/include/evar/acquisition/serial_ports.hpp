#pragma once
// The serial ports a C-arm link could be on: USB-serial adapters (ttyUSB*, ttyACM*),
// on-board UARTs that have hardware behind them (ttyS* the kernel reports a UART type for,
// ttyAMA*, ttyTHS*), with the stable names udev gives them under serial/by-id.
#include <filesystem>
#include <string>
#include <vector>

namespace evar::acquisition {

struct SerialPortInfo {
  std::string path;                 ///< /dev/ttyUSB0
  std::string kind;                 ///< "USB serial", "USB CDC ACM", "UART"
  std::vector<std::string> by_id;   ///< /dev/serial/by-id/... links to it (stable across replugging)
};

/// Ports under `dev_dir`; whether a ttyS* has a UART is read from `sys_class_tty`/ttySN/type
/// (no port is opened).
std::vector<SerialPortInfo> list_serial_ports(const std::filesystem::path& dev_dir = "/dev",
                                              const std::filesystem::path& sys_class_tty = "/sys/class/tty");

}  // namespace evar::acquisition
