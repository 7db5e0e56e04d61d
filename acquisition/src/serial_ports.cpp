#include "evar/acquisition/serial_ports.hpp"

#include <linux/serial.h>

#include <algorithm>
#include <fstream>
#include <cctype>
#include <map>
#include <system_error>

namespace evar::acquisition {

namespace {

namespace fs = std::filesystem;

// ttyS0..31 exist whether or not a UART is behind them; sysfs says which have one (its
// type is not PORT_UNKNOWN). Read there rather than by opening the port: opening a tty
// raises DTR and RTS, and closing drops them, which resets some attached equipment.
bool uart_present(const fs::path& sys_class_tty, const std::string& name) {
  std::ifstream in(sys_class_tty / name / "type");
  int type = PORT_UNKNOWN;
  return (in >> type) && type != PORT_UNKNOWN;
}

// "ttyUSB10" → ("ttyUSB", 10) so ports sort in number order.
std::pair<std::string, long> sort_key(const std::string& name) {
  std::size_t i = name.size();
  while (i > 0 && std::isdigit(static_cast<unsigned char>(name[i - 1]))) --i;
  return {name.substr(0, i), i < name.size() ? std::stol(name.substr(i, 9)) : -1};
}

}  // namespace

std::vector<SerialPortInfo> list_serial_ports(const fs::path& dev_dir, const fs::path& sys_class_tty) {
  std::error_code ec;
  std::map<std::string, std::vector<std::string>> links;  // canonical target → by-id links
  for (const auto& e : fs::directory_iterator(dev_dir / "serial" / "by-id", ec)) {
    const fs::path target = fs::weakly_canonical(e.path(), ec);
    if (!ec) links[target.string()].push_back(e.path().string());
  }
  std::vector<std::pair<std::pair<std::string, long>, SerialPortInfo>> found;
  for (const auto& e : fs::directory_iterator(dev_dir, ec)) {
    const std::string name = e.path().filename().string();
    std::string kind;
    if (name.starts_with("ttyUSB")) kind = "USB serial";
    else if (name.starts_with("ttyACM")) kind = "USB CDC ACM";
    else if (name.starts_with("ttyAMA") || name.starts_with("ttyTHS")) kind = "UART";
    else if (name.starts_with("ttyS") && uart_present(sys_class_tty, name)) kind = "UART";
    if (kind.empty()) continue;
    SerialPortInfo info{e.path().string(), kind, {}};
    const fs::path canonical = fs::weakly_canonical(e.path(), ec);
    if (auto it = links.find(canonical.string()); it != links.end()) {
      info.by_id = it->second;
      std::sort(info.by_id.begin(), info.by_id.end());
    }
    found.emplace_back(sort_key(name), std::move(info));
  }
  std::sort(found.begin(), found.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<SerialPortInfo> out;
  for (auto& f : found) out.push_back(std::move(f.second));
  return out;
}

}  // namespace evar::acquisition
