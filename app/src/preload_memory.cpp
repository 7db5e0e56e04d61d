#include "preload_memory.hpp"

#include <unistd.h>

#include <stdexcept>
#include <string>

#include "evar/node/logging.hpp"
#include "evar/session/session_replay.hpp"

namespace evar::app {

void check_preload_memory(const session::Session& session) {
  const std::uint64_t need = session::preload_bytes(session);
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  const std::uint64_t have = pages > 0 && page > 0 ? static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(page) : 0;
  const auto [cols, rows] = session::frame_size_px(session);
  const std::string sizes = std::to_string(session.frames.size()) + " frames of " + std::to_string(cols) +
                            " x " + std::to_string(rows) + " at 16 bits: " +
                            std::to_string(need >> 20) + " MiB";
  if (have > 0 && need > have / 2)
    throw std::runtime_error("--preload: " + sizes + ", more than half this machine's " + std::to_string(have >> 20) +
                             " MiB; replay without --preload");
  node::log().info("preloading {} before the replay starts", sizes);
}

}  // namespace evar::app
