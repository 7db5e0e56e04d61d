#pragma once
// A pseudo-terminal pair: the master end is a C-arm adapter's side of a serial cable, the
// slave path is what the node opens as its serial port. Used to serve recorded sessions
// over the real serial code path, and by the hardware-in-the-loop tests.
#include <cstdint>
#include <span>
#include <string>

#include "evar/base/unique_fd.hpp"

namespace evar::sim {

class PseudoTerminal {
 public:
  /// Opens a pair (raw mode on both ends). With `link`, also makes a symbolic link at that
  /// path to the slave (replacing an old link), as `socat pty,link=…` does, so a reader can
  /// be pointed at a stable name across reconnections. Throws std::runtime_error.
  explicit PseudoTerminal(const std::string& link = {});
  ~PseudoTerminal();  // closes both ends (the reader sees a hangup) and removes the link
  PseudoTerminal(const PseudoTerminal&) = delete;
  PseudoTerminal& operator=(const PseudoTerminal&) = delete;

  const std::string& slave_path() const { return slave_path_; }
  /// Writes all of `bytes` to the master end (blocking until written); throws on error.
  void write(std::span<const std::uint8_t> bytes);
  /// Writes what fits now; false when the pty's buffer was full and the message was
  /// dropped (as on a serial line that nobody reads). A message partly written is finished
  /// if room comes within 200 ms, else the rest is dropped too (the reader's decoder
  /// resynchronises at the next delimiter). Never waits longer. Throws on other errors.
  bool write_or_drop(std::span<const std::uint8_t> bytes);

 private:
  base::UniqueFd master_;
  base::UniqueFd slave_;  // held open so the slave side does not report hangup before the reader opens it
  std::string slave_path_, link_;
};

}  // namespace evar::sim
