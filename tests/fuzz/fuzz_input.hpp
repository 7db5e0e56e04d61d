#pragma once
// Shared by the fuzz harnesses: the input as files in a private temporary folder (the
// parsers under test read files), and the rule every harness enforces: a parser may
// reject its input only with base::InputError, whose message names the file.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <string_view>
#include <typeinfo>
#include <vector>

#include "evar/base/input_error.hpp"

namespace evar::fuzz {

/// A folder for this process's inputs, removed at exit.
inline const std::filesystem::path& scratch() {
  static const std::filesystem::path dir = [] {
    std::string pattern = (std::filesystem::temp_directory_path() / "evar-fuzz-XXXXXX").string();
    if (!::mkdtemp(pattern.data())) std::abort();
    static const std::filesystem::path removed_at_exit = pattern;
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(removed_at_exit, ec);
    });
    return std::filesystem::path(pattern);
  }();
  return dir;
}

inline std::filesystem::path write_file(const std::string& name, std::span<const std::uint8_t> bytes) {
  const auto path = scratch() / name;
  std::filesystem::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (!out) std::abort();
  return path;
}

/// Splits the input at each line "--8<--" (the corpora stay readable text): several files
/// from one input.
inline std::vector<std::span<const std::uint8_t>> split_parts(const std::uint8_t* data, std::size_t size, std::size_t parts) {
  static constexpr std::string_view kCut = "\n--8<--\n";
  std::vector<std::span<const std::uint8_t>> out;
  const std::string_view all(reinterpret_cast<const char*>(data), size);
  std::size_t start = 0;
  while (out.size() + 1 < parts) {
    const auto at = all.find(kCut, start);
    if (at == std::string_view::npos) break;
    out.emplace_back(data + start, at - start);
    start = at + kCut.size();
  }
  out.emplace_back(data + start, size - start);
  while (out.size() < parts) out.emplace_back();
  return out;
}

/// Runs `parse`; an InputError is a correct rejection. Any other exception is a finding:
/// reported and aborted, so libFuzzer keeps the input.
template <typename Parse>
void expect_input_error_only(Parse&& parse) {
  try {
    parse();
  } catch (const base::InputError&) {
    throw;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "not an evar::base::InputError (%s): %s\n", typeid(e).name(), e.what());
    std::abort();
  }
}

/// As expect_input_error_only, and the InputError must name `file`.
template <typename Parse>
void expect_clean_rejection(const std::filesystem::path& file, Parse&& parse) {
  try {
    expect_input_error_only(parse);
  } catch (const base::InputError& e) {
    if (std::string_view(e.what()).find(file.filename().string()) == std::string_view::npos) {
      std::fprintf(stderr, "evar::base::InputError without the file name %s: %s\n", file.filename().c_str(), e.what());
      std::abort();
    }
  }
}

/// As expect_input_error_only, for inputs of several files (the error names whichever is wrong).
template <typename Parse>
void expect_rejection_as_input_error(Parse&& parse) {
  try {
    expect_input_error_only(parse);
  } catch (const base::InputError&) {
  }
}

}  // namespace evar::fuzz
