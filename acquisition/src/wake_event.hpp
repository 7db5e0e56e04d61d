#pragma once
// An eventfd that a source's stop() signals to wake its thread out of poll(); owned, so it
// is closed with the source.
#include <poll.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>

#include "evar/base/unique_fd.hpp"

namespace evar::acquisition {

class WakeEvent {
 public:
  explicit WakeEvent(const char* owner) : fd_(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK)) {
    if (!fd_) throw std::runtime_error(std::string(owner) + ": eventfd: " + std::strerror(errno));
  }

  /// For poll() beside the thread's own descriptors (POLLIN once signalled).
  int fd() const { return fd_.get(); }
  void signal() {
    const std::uint64_t one = 1;
    [[maybe_unused]] const ssize_t n = ::write(fd_.get(), &one, sizeof one);
  }
  /// Forgets an earlier signal (before a restart).
  void clear() {
    std::uint64_t count = 0;
    while (::read(fd_.get(), &count, sizeof count) > 0) {
    }
  }
  /// Sleeps up to `d`; true when signalled.
  bool wait(std::chrono::milliseconds d) const {
    pollfd p{fd_.get(), POLLIN, 0};
    return ::poll(&p, 1, static_cast<int>(d.count())) > 0;
  }

 private:
  base::UniqueFd fd_;
};

}  // namespace evar::acquisition
