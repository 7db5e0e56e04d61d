#pragma once
// The seam under every V4L2 call: open, close, ioctl, mmap, munmap and poll, with libc's
// conventions (−1 / MAP_FAILED and errno). The grabber talks to the kernel only through
// this, so its whole logic (negotiation, streaming, drops, watchdog, reopen) can be driven
// by a scripted device where no /dev/video* exists.
#include <poll.h>
#include <sys/types.h>

#include <cstddef>

namespace evar::acquisition {

class V4l2Io {
 public:
  virtual ~V4l2Io() = default;
  virtual int open(const char* path, int flags) = 0;
  virtual int close(int fd) = 0;
  virtual int ioctl(int fd, unsigned long request, void* arg) = 0;
  virtual void* mmap(std::size_t length, int prot, int flags, int fd, off_t offset) = 0;
  virtual int munmap(void* address, std::size_t length) = 0;
  /// Polls `fds`, which may mix device descriptors with the caller's own (an eventfd).
  virtual int poll(pollfd* fds, nfds_t count, int timeout_ms) = 0;
};

/// The kernel: the libc calls themselves.
V4l2Io& system_v4l2_io();

}  // namespace evar::acquisition
