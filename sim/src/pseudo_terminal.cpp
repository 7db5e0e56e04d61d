#include "evar/sim/pseudo_terminal.hpp"

#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "evar/base/unique_fd.hpp"

namespace evar::sim {


PseudoTerminal::PseudoTerminal(const std::string& link) {
  termios raw{};
  ::cfmakeraw(&raw);
  char name[256] = {};
  int master = -1, slave = -1;
  if (::openpty(&master, &slave, name, &raw, nullptr) != 0)
    throw std::runtime_error(std::string("pseudo-terminal: openpty failed: ") + std::strerror(errno));
  master_.reset(master);
  slave_.reset(slave);
  ::fcntl(master_.get(), F_SETFD, FD_CLOEXEC);
  ::fcntl(master_.get(), F_SETFL, ::fcntl(master_.get(), F_GETFL) | O_NONBLOCK);  // write() waits by poll, write_or_drop() not
  ::fcntl(slave_.get(), F_SETFD, FD_CLOEXEC);
  slave_path_ = name;
  if (!link.empty()) {
    struct stat st {};
    if (::lstat(link.c_str(), &st) == 0 && !S_ISLNK(st.st_mode)) {
      throw std::runtime_error("pseudo-terminal: " + link + " exists and is not a symbolic link; not replacing it");
    }
    const std::string tmp = link + ".new";
    ::unlink(tmp.c_str());
    // Made beside the target and renamed over it, so a reader never sees no link at all.
    if (::symlink(slave_path_.c_str(), tmp.c_str()) != 0 || ::rename(tmp.c_str(), link.c_str()) != 0) {
      const std::string why = std::strerror(errno);
      ::unlink(tmp.c_str());
      throw std::runtime_error("pseudo-terminal: cannot link " + link + " to " + slave_path_ + ": " + why);
    }
    link_ = link;
  }
}

PseudoTerminal::~PseudoTerminal() {
  if (!link_.empty()) {
    // Only our own link: a newer pair may have replaced it already.
    char target[256] = {};
    const ssize_t n = ::readlink(link_.c_str(), target, sizeof target - 1);
    if (n > 0 && slave_path_ == std::string(target, static_cast<std::size_t>(n))) ::unlink(link_.c_str());
  }
  // The descriptors close after this, the slave first.
}

bool PseudoTerminal::write_or_drop(std::span<const std::uint8_t> bytes) {
  ssize_t n = 0;
  do n = ::write(master_.get(), bytes.data(), bytes.size());
  while (n < 0 && errno == EINTR);
  if (n < 0 && errno == EAGAIN) return false;  // nothing of it went out: dropped whole
  if (n < 0) throw std::runtime_error("pseudo-terminal " + slave_path_ + ": write failed: " + std::strerror(errno));
  // Part of a message may be out: finish it if the reader makes room soon. One that does
  // not read at all gets a torn frame, which its decoder drops at the next delimiter;
  // waiting for it would hang the sender (a replay nobody listens to).
  auto done = static_cast<std::size_t>(n);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(200);
  while (done < bytes.size()) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return false;
    pollfd p{master_.get(), POLLOUT, 0};
    if (::poll(&p, 1, static_cast<int>(left.count())) < 0 && errno != EINTR)
      throw std::runtime_error("pseudo-terminal " + slave_path_ + ": poll failed: " + std::strerror(errno));
    n = ::write(master_.get(), bytes.data() + done, bytes.size() - done);
    if (n > 0) done += static_cast<std::size_t>(n);
    else if (n < 0 && errno != EINTR && errno != EAGAIN)
      throw std::runtime_error("pseudo-terminal " + slave_path_ + ": write failed: " + std::strerror(errno));
  }
  return true;
}

void PseudoTerminal::write(std::span<const std::uint8_t> bytes) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(master_.get(), bytes.data() + done, bytes.size() - done);
    if (n > 0) {
      done += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && errno == EAGAIN) {
      pollfd p{master_.get(), POLLOUT, 0};
      ::poll(&p, 1, 100);
      continue;
    }
    throw std::runtime_error("pseudo-terminal " + slave_path_ + ": write failed: " + std::strerror(errno));
  }
}

}  // namespace evar::sim
