#pragma once
// Machine-readable reports beside the human log lines.
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "evar/base/atomic_file.hpp"

namespace evar::app {

inline void write_text(const std::filesystem::path& path, const std::string& text) {
  base::write_file_atomically(path, text);
}

inline void write_json(const std::filesystem::path& path, const nlohmann::json& j) { write_text(path, j.dump(2) + '\n'); }

}  // namespace evar::app
