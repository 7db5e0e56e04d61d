#pragma once
// The C-arm geometry over a serial line (RS-232, USB-serial adapter, or a pseudo-terminal)
// speaking the C-arm link protocol. Reconnects on its own after a hangup or a missing
// device: the node never has to be restarted because a cable was pulled.
#include <chrono>
#include <memory>
#include <string>

#include "evar/acquisition/carm_geometry_source.hpp"
#include "evar/acquisition/carm_link_statistics.hpp"
#include "evar/acquisition/serial_settings.hpp"

namespace evar::acquisition {

struct SerialLinkOptions {
  std::string path;                                   ///< /dev/ttyUSB0, /dev/ttyS0, a pty or a link to one
  SerialSettings settings;
  std::chrono::milliseconds reconnect_interval{250};  ///< between attempts to reopen
  std::chrono::milliseconds stale_after{1000};        ///< no geometry for this long → Stalled
};

class SerialCArmSource final : public CArmGeometrySource {
 public:
  explicit SerialCArmSource(SerialLinkOptions options);
  ~SerialCArmSource() override;

  /// Starts the link thread. Never throws for a missing device: it keeps trying and reports
  /// Connecting with the reason. Callbacks run on the link thread; they may ask for state()
  /// and statistics() but must not call start() or stop().
  void start(StateCallback on_state, StreamCallback on_stream, NoticeCallback on_notice) override;
  void stop() override;
  StreamState state() const override;
  std::string description() const override;
  CArmLinkStatistics statistics() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace evar::acquisition
