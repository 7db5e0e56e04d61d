// `evarnode replay`: plays a recorded session through the acquisition interfaces and
// reports what arrived.
#include <map>
#include <mutex>
#include <optional>
#include <set>

#include "commands.hpp"
#include "evar/node/logging.hpp"
#include "evar/session/session_replay.hpp"
#include "evar/sim/gige_frame_server.hpp"
#include "evar/sim/serial_carm_server.hpp"
#include "interrupt.hpp"
#include "json_file.hpp"
#include "preload_memory.hpp"
#include "progress_bar.hpp"

namespace evar::app {

int run_replay(const ReplayCommand& cmd) {
  const session::Session session = session::read_session(cmd.session);
  if (session.frames.empty()) {
    node::log().error("{}: the session has no frames", cmd.session.string());
    return 1;
  }
  // What the callbacks fill in: declared before the replay, so it outlives the replay's
  // thread whatever happens.
  std::mutex m;
  std::map<std::string, std::size_t> by_view;  // frames per settled view
  std::size_t frames_while_moving = 0, moving_states = 0;
  std::optional<acquisition::CArmState> in_force;
  std::optional<std::int64_t> first_ns;
  std::int64_t last_ns = 0;
  // The real transports' far ends, when asked: the node (or a viewer) on the other side
  // receives through its real GigE and serial sources.
  std::optional<sim::GigEFrameServer> camera;
  std::optional<sim::SerialCArmServer> carm_link;
  if (!cmd.serve_gige.empty()) {
    camera.emplace(cmd.serve_gige, cmd.gige_interface);
    node::log().info("serving the frames as GigE Vision camera {} on interface {}", camera->device_id(), cmd.gige_interface);
  }
  if (!cmd.serve_carm.empty()) {
    carm_link.emplace(cmd.serve_carm);
    node::log().info("serving the C-arm states on {} (-> {}), C-arm link protocol v1", cmd.serve_carm, carm_link->slave_path());
  }
  std::string transport_error;  // the first failure to serve; the replay goes on
  if (cmd.preload) check_preload_memory(session);
  session::SessionReplay replay(session, {cmd.fast ? 0.0 : cmd.speed, cmd.loops, cmd.preload});
  const InterruptGuard ctrl_c;  // Ctrl-C stops the replay cleanly
  replay.carm().start(
      [&](const acquisition::CArmState& s) {
        std::string failed;  // the link is written outside the report's lock
        if (carm_link) {
          try {
            carm_link->send(s);
          } catch (const std::exception& e) {
            failed = e.what();
          }
        }
        std::lock_guard lock(m);
        if (transport_error.empty()) transport_error = failed;
        in_force = s;
        moving_states += s.moving ? 1 : 0;
      },
      nullptr, nullptr);
  replay.frames().start(
      [&](const acquisition::Frame& f) {
        if (camera) camera->show(f);  // outside the report's lock: it copies the whole frame
        std::lock_guard lock(m);
        if (!first_ns) first_ns = f.device_time_ns;
        last_ns = f.device_time_ns;
        if (!in_force) return;
        if (in_force->moving) ++frames_while_moving;
        char view[64];
        std::snprintf(view, sizeof view, "%+.0f/%+.0f", in_force->primary_deg, in_force->secondary_deg);
        ++by_view[view];
      },
      [&](acquisition::StreamState s, const std::string& reason) {
        node::log().debug("frame source: {} ({})", acquisition::to_string(s), reason);
      });

  ProgressBar bar("frames", cmd.progress);
  const std::size_t total = cmd.loops == 0 ? 0 : session.frames.size() * static_cast<std::size_t>(cmd.loops);
  const auto start = std::chrono::steady_clock::now();
  while (!replay.wait(std::chrono::milliseconds(100))) {
    if (ctrl_c.interrupted()) {
      replay.frames().stop();
      break;
    }
    const auto p = replay.progress();
    bar.update(p.frames, total ? total : p.frames + p.frames_per_loop);
  }
  const auto p = replay.progress();
  bar.update(p.frames, total ? total : p.frames);
  bar.finish();
  replay.frames().stop();
  replay.carm().stop();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  const auto stats = replay.frames().statistics();
  node::log().info("{}: {} frames ({} dropped) and {} C-arm states in {:.1f} s ({:.1f} frames/s), {} loop(s)", cmd.session.string(),
             p.frames, stats.dropped, p.carm_states, seconds, p.frames / std::max(seconds, 1e-9), p.loop + 1);
  for (const auto& [view, n] : by_view) node::log().info("  view {} (primary/secondary deg): {} frames", view, n);
  if (frames_while_moving > 0) node::log().warn("  {} frames arrived while the C-arm was moving", frames_while_moving);
  if (!replay.error().empty()) node::log().error("replay stopped early: {}", replay.error());
  if (camera) node::log().info("  GigE camera {}: {} frames sent", camera->device_id(), camera->frames_sent());
  if (carm_link)
    node::log().info("  C-arm link {}: {} states sent, {} dropped (nobody reading)", cmd.serve_carm, carm_link->sent(),
               carm_link->dropped());
  if (!transport_error.empty()) node::log().error("serving the C-arm link failed: {}", transport_error);
  if (!cmd.report.empty()) {
    nlohmann::json views = nlohmann::json::object();
    for (const auto& [view, n] : by_view) views[view] = n;
    write_json(cmd.report, {{"format", "evarnode-replay-report"},
                            {"version", 1},
                            {"session", cmd.session.string()},
                            {"frames", p.frames},
                            {"dropped", stats.dropped},
                            {"carm_states", p.carm_states},
                            {"carm_moving_states", moving_states},
                            {"frames_while_moving", frames_while_moving},
                            {"loops", p.loop + 1},
                            {"seconds", seconds},
                            {"device_seconds", static_cast<double>(last_ns - first_ns.value_or(last_ns)) * 1e-9},
                            {"frames_per_view", views},
                            {"interrupted", ctrl_c.interrupted()},
                            {"error", replay.error()}});
  }
  return replay.error().empty() ? 0 : 1;
}

}  // namespace evar::app
