#include "evar/sim/serial_carm_server.hpp"

#include "evar/acquisition/carm_link_protocol.hpp"

namespace evar::sim {

SerialCArmServer::SerialCArmServer(const std::string& link) : pty_(link) {}

void SerialCArmServer::send(const acquisition::CArmState& state) {
  acquisition::carm_link::GeometryMessage m;
  m.sequence = sequence_;
  m.state = state;
  const bool whole = pty_.write_or_drop(acquisition::carm_link::encode(m));
  ++sequence_;  // wraps at 2^16, as the protocol says; a dropped one shows as a gap
  ++(whole ? sent_ : dropped_);
}

}  // namespace evar::sim
