#pragma once
// Plays C-arm states as a C-arm-side adapter would: the C-arm link protocol written to the
// master end of a pseudo-terminal, whose slave (or the stable link given) the node opens as
// its serial port.
#include <cstdint>
#include <string>

#include "evar/acquisition/carm_geometry_source.hpp"
#include "evar/sim/pseudo_terminal.hpp"

namespace evar::sim {

class SerialCArmServer {
 public:
  /// `link`: a path made into a symbolic link to the pty's slave (empty: none).
  explicit SerialCArmServer(const std::string& link = {});
  /// Sends one geometry sample (sequence numbers count up from 0); throws for values the
  /// protocol cannot carry. Never waits: while nobody reads the link and its buffer is
  /// full, samples are dropped (and counted), as on a serial line nobody listens to.
  void send(const acquisition::CArmState& state);
  std::uint64_t dropped() const { return dropped_; }
  const std::string& slave_path() const { return pty_.slave_path(); }
  std::uint64_t sent() const { return sent_; }

 private:
  sim::PseudoTerminal pty_;
  std::uint16_t sequence_ = 0;
  std::uint64_t sent_ = 0, dropped_ = 0;
};

}  // namespace evar::sim
