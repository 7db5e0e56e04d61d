#include "evar/base/atomic_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <string>
#include <system_error>
#include <vector>

namespace evar::base {
namespace {

constexpr std::size_t kBufferBytes = 1 << 16;

bool exists_as_non_regular(const std::filesystem::path& p) {
  struct stat st {};
  return ::stat(p.c_str(), &st) == 0 && !S_ISREG(st.st_mode);
}

std::string reason(int error) {
  std::string r = std::strerror(error);
  if (error == ENOSPC || error == EDQUOT) r += " (disk full?)";
  return r;
}

}  // namespace

AtomicFile::AtomicFile(std::filesystem::path target, Durability durability)
    : target_(std::move(target)), durability_(durability) {
  if (target_.empty()) throw std::system_error(EINVAL, std::generic_category(), "cannot write a file with no name");
  if (exists_as_non_regular(target_)) {
    fd_.reset(::open(target_.c_str(), O_WRONLY | O_CLOEXEC | O_NOCTTY));
    if (!fd_) fail("cannot open for writing", errno);
    return;
  }
  // mkstemp wants a writable template; the partial name is unique, so two writers of the
  // same target never write into one file, and a stale one from a crash is never reused.
  std::string name = target_.string() + ".partial-XXXXXX";
  std::vector<char> tmpl(name.begin(), name.end());
  tmpl.push_back('\0');
  fd_.reset(::mkostemp(tmpl.data(), O_CLOEXEC));
  if (!fd_) fail("cannot create a file beside it", errno);
  partial_ = tmpl.data();
  // mkstemp creates 0600; an output is as readable as any file the user creates.
  const mode_t mask = ::umask(0);
  ::umask(mask);
  ::fchmod(fd_.get(), 0666 & ~mask);
  buffer_.reserve(kBufferBytes);
}

AtomicFile::~AtomicFile() {
  if (committed_ || partial_.empty()) return;
  fd_.reset();
  ::unlink(partial_.c_str());
}

void AtomicFile::fail(const char* what, int error) const {
  throw std::system_error(error, std::generic_category(), target_.string() + ": " + what + ": " + reason(error));
}

void AtomicFile::flush() {
  std::size_t done = 0;
  while (done < buffer_.size()) {
    const ssize_t n = ::write(fd_.get(), buffer_.data() + done, buffer_.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) fail("cannot write", errno);
    if (n == 0) fail("cannot write", EIO);
    done += static_cast<std::size_t>(n);
  }
  buffer_.clear();
}

void AtomicFile::write(std::string_view bytes) {
  if (committed_) throw std::logic_error(target_.string() + ": written after commit");
  if (buffer_.size() + bytes.size() > kBufferBytes) flush();
  if (bytes.size() >= kBufferBytes) {
    buffer_.assign(bytes);
    flush();
    return;
  }
  buffer_.append(bytes);
}

void AtomicFile::commit() {
  if (committed_) throw std::logic_error(target_.string() + ": committed twice");
  flush();
  if (partial_.empty()) {  // a device or FIFO: written in place, nothing to rename
    if (::close(fd_.release()) != 0) fail("cannot write", errno);
    committed_ = true;
    return;
  }
  if (durability_ == Durability::Synced && ::fsync(fd_.get()) != 0) fail("cannot write", errno);
  if (::close(fd_.release()) != 0) fail("cannot write", errno);
  if (::rename(partial_.c_str(), target_.c_str()) != 0) {
    const int e = errno;
    ::unlink(partial_.c_str());
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

}  // namespace evar::base
