#include "evar/geometry/input_file.hpp"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <system_error>

#include "evar/geometry/input_error.hpp"

namespace evar::geometry {
namespace {

[[noreturn]] void fail(const std::filesystem::path& file, const std::string& what) {
  throw InputError(file.string() + ": " + what);
}

// Exact: "64 MiB", or "67108865 bytes" when not a whole number of MiB.
std::string size_text(std::uintmax_t bytes) {
  if (bytes >= kMiB && bytes % kMiB == 0) return std::to_string(bytes / kMiB) + " MiB";
  return std::to_string(bytes) + " bytes";
}

[[noreturn]] void too_large(const std::filesystem::path& file, std::uintmax_t bytes, InputLimit limit) {
  fail(file, "is " + size_text(bytes) + ", more than the " + size_text(limit.bytes) + " accepted for " + limit.kind +
                 "; refusing to read it");
}

}  // namespace

void check_input_file(const std::filesystem::path& file, InputLimit limit) {
  std::error_code ec;
  const auto status = std::filesystem::status(file, ec);
  if (status.type() == std::filesystem::file_type::not_found) fail(file, "file does not exist");
  if (ec) fail(file, "cannot access: " + ec.message());
  if (std::filesystem::is_directory(status)) fail(file, "is a directory, not a file");
  if (!std::filesystem::is_regular_file(status)) fail(file, "is not a regular file");
  const std::uintmax_t bytes = std::filesystem::file_size(file, ec);
  if (ec) fail(file, "cannot read its size: " + ec.message());
  if (bytes > limit.bytes) too_large(file, bytes, limit);
}

std::string read_input_file(const std::filesystem::path& file, InputLimit limit) {
  check_input_file(file, limit);
  std::ifstream in(file, std::ios::binary);
  if (!in) fail(file, std::string("cannot open: ") + std::strerror(errno));
  std::string bytes;
  char chunk[1 << 16];
  while (in.read(chunk, sizeof chunk) || in.gcount() > 0) {
    bytes.append(chunk, static_cast<std::size_t>(in.gcount()));
    if (bytes.size() > limit.bytes) too_large(file, bytes.size(), limit);
  }
  if (in.bad()) fail(file, "read error");
  return bytes;
}

}  // namespace evar::geometry
