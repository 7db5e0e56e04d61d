#pragma once
// What a C-arm link (serial or USB) has seen: the decoder's counters, connections, the last
// error and the C-arm's last status message.
#include <cstdint>
#include <optional>
#include <string>

#include "evar/acquisition/carm_link_protocol.hpp"

namespace evar::acquisition {

struct CArmLinkStatistics {
  carm_link::LinkStats link;
  std::uint64_t connections = 0;   ///< times the transport came up
  std::uint64_t disconnections = 0;
  std::string last_error;          ///< the decoder's last error, with the byte it ended at
  std::optional<carm_link::StatusMessage> last_status;
  std::uint64_t statuses_not_reported = 0;  ///< status warnings past the most reported in one notice interval
};

}  // namespace evar::acquisition
