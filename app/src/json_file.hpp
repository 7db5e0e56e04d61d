#pragma once
// Machine-readable reports beside the human log lines.
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

namespace evar::app {

inline void write_text(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  if (!out) throw std::runtime_error(path.string() + ": cannot write");
}

inline void write_json(const std::filesystem::path& path, const nlohmann::json& j) { write_text(path, j.dump(2) + '\n'); }

}  // namespace evar::app
