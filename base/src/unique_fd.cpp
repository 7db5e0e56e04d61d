#include "evar/base/unique_fd.hpp"

#include <unistd.h>

namespace evar::base {

void UniqueFd::reset(int fd) {
  // close() is not retried on EINTR: on Linux the descriptor is gone either way.
  if (fd_ >= 0 && fd_ != fd) ::close(fd_);
  fd_ = fd;
}

}  // namespace evar::base
