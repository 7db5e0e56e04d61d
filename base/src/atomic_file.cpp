#include "evar/base/atomic_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <stdexcept>
#include <system_error>

namespace evar::base {
namespace {

constexpr std::size_t kBufferBytes = 1 << 16;

std::string hint(int error) { return error == ENOSPC || error == EDQUOT ? " (disk full?)" : ""; }

// A name beside the target that no other writer, in this process or another, picks.
std::string partial_name(const std::filesystem::path& target) {
  static std::atomic<unsigned> counter{0};
  const auto ticks = static_cast<unsigned long long>(std::chrono::steady_clock::now().time_since_epoch().count());
  char suffix[64];
  std::snprintf(suffix, sizeof suffix, ".partial-%d-%u-%llx", static_cast<int>(::getpid()), counter++, ticks & 0xffffffULL);
  return target.string() + suffix;
}

}  // namespace

AtomicFile::AtomicFile(std::filesystem::path target, Durability durability)
    : target_(std::move(target)), durability_(durability) {
  if (target_.empty()) throw std::system_error(EINVAL, std::generic_category(), "cannot write a file with no name");
  buffer_.reserve(kBufferBytes);
  struct stat link {};
  const bool exists = ::lstat(target_.c_str(), &link) == 0;
  const auto in_place = [&] {
    fd_.reset(::open(target_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC | O_NOCTTY, 0666));
    if (!fd_) fail("cannot open for writing", errno);
  };
  if (exists && !S_ISREG(link.st_mode)) {  // a link, device or FIFO
    in_place();
    return;
  }
  // A file we may not write is not replaced behind its back.
  if (exists && ::access(target_.c_str(), W_OK) != 0) fail("cannot write", errno);
  for (int attempt = 0; attempt < 16 && !fd_; ++attempt) {
    partial_ = partial_name(target_);
    // The kernel applies the umask to 0666, as for any file the user creates.
    fd_.reset(::open(partial_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOCTTY, 0666));
    if (!fd_ && errno != EEXIST) break;
  }
  if (!fd_) {
    const int e = errno;
    partial_.clear();
    // An existing file in a folder we may not add to is still ours to write.
    if (exists && (e == EACCES || e == EPERM || e == EROFS)) {
      in_place();
      return;
    }
    fail("cannot create a file beside it", e);
  }
  if (exists) ::fchmod(fd_.get(), link.st_mode & 07777);  // the old file's permissions
}

AtomicFile::~AtomicFile() {
  if (committed_ || partial_.empty()) return;
  fd_.reset();
  ::unlink(partial_.c_str());
}

void AtomicFile::fail(const char* what, int error) const {
  throw std::system_error(error, std::generic_category(), target_.string() + ": " + what + hint(error));
}

void AtomicFile::write_out(std::string_view bytes) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_.get(), bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) fail("cannot write", errno);
    if (n == 0) fail("cannot write", EIO);
    done += static_cast<std::size_t>(n);
  }
}

void AtomicFile::flush() {
  write_out(buffer_);
  buffer_.clear();
}

void AtomicFile::write(std::string_view bytes) {
  if (committed_) throw std::logic_error(target_.string() + ": written after commit");
  if (buffer_.size() + bytes.size() <= kBufferBytes) {
    buffer_.append(bytes);
    return;
  }
  flush();
  if (bytes.size() >= kBufferBytes) write_out(bytes);  // large: straight from the caller's bytes
  else buffer_.append(bytes);
}

void AtomicFile::commit() {
  if (committed_) throw std::logic_error(target_.string() + ": committed twice");
  flush();
  if (durability_ == Durability::Synced && !partial_.empty() && ::fsync(fd_.get()) != 0) fail("cannot write", errno);
  if (::close(fd_.release()) != 0) fail("cannot write", errno);
  if (partial_.empty()) {  // written in place: nothing to rename
    committed_ = true;
    return;
  }
  if (::rename(partial_.c_str(), target_.c_str()) != 0) {
    const int e = errno;
    ::unlink(partial_.c_str());
    partial_.clear();
    fail("cannot put the written file in place", e);
  }
  committed_ = true;
  if (durability_ == Durability::Synced) {
    // The rename is the directory's change: synced, it survives a power cut. A directory
    // that cannot be opened for it (permissions) still has the file; nothing to report.
    const std::filesystem::path dir = target_.has_parent_path() ? target_.parent_path() : ".";
    const UniqueFd d(::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
    if (d) ::fsync(d.get());
  }
}

void write_file_atomically(const std::filesystem::path& target, std::string_view bytes, Durability durability) {
  AtomicFile file(target, durability);
  file.write(bytes);
  file.commit();
}

bool sync_filesystem_of(const std::filesystem::path& path) {
  const UniqueFd fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  return fd && ::syncfs(fd.get()) == 0;
}

}  // namespace evar::base
