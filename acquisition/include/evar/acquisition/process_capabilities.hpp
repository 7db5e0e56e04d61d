#pragma once
// Which Linux capabilities the node holds. The bedside service runs unprivileged and is
// granted CAP_NET_RAW only when the site wants Aravis's packet socket (scripts/bedside/), so the
// GigE source asks before using it instead of relying on running as root.
#include <optional>
#include <string_view>

namespace evar::acquisition {

inline constexpr int kCapNetRaw = 13;  ///< CAP_NET_RAW in <linux/capability.h>

/// Bit `capability` of the "CapEff:" line of a /proc/<pid>/status text; nullopt when the
/// line is missing or not hexadecimal.
std::optional<bool> effective_capability_in_status(std::string_view status_text, int capability);

/// This process's effective set (from /proc/self/status); false when it cannot be read.
bool has_effective_capability(int capability);

}  // namespace evar::acquisition
