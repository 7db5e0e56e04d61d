#include "evar/base/input_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <system_error>

#include "evar/base/unique_fd.hpp"
#include "evar/base/input_error.hpp"

namespace evar::base {
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
  check_input_file(file, limit);  // the clear messages (missing, a directory, too large)
  // What was checked may be replaced before it is opened: the descriptor is checked again.
  // O_NONBLOCK, so that a FIFO put there cannot hold the open.
  const base::UniqueFd owned(::open(file.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY));
  if (!owned) fail(file, std::string("cannot open: ") + std::strerror(errno));
  const int fd = owned.get();
  struct stat st {};
  if (::fstat(fd, &st) != 0) fail(file, std::string("cannot read its status: ") + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) fail(file, "is not a regular file");
  if (static_cast<std::uintmax_t>(st.st_size) > limit.bytes) too_large(file, static_cast<std::uintmax_t>(st.st_size), limit);
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  std::string bytes;
  bytes.reserve(static_cast<std::size_t>(st.st_size));
  char chunk[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, chunk, sizeof chunk);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) fail(file, std::string("read error: ") + std::strerror(errno));
    if (n == 0) break;
    bytes.append(chunk, static_cast<std::size_t>(n));
    if (bytes.size() > limit.bytes) too_large(file, bytes.size(), limit);  // it grew while read
  }
  return bytes;
}

}  // namespace evar::base
