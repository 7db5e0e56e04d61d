// `evarnode export`: a recorded session as a PLUS sequence metafile for 3D Slicer.
#include <filesystem>

#include "commands.hpp"
#include "evar/base/input_error.hpp"
#include "evar/node/logging.hpp"
#include "evar/session/session.hpp"
#include "progress_bar.hpp"

namespace evar::app {

int run_export(const ExportCommand& cmd) {
  const session::Session session = session::read_session(cmd.session);
  if (session.frames.empty()) throw base::InputError(cmd.session.string() + ": the session has no frames");
  const std::string name = cmd.out.filename().string();
  if (name.size() < 8 || name.compare(name.size() - 8, 8, ".seq.mha") != 0)
    node::log().warn("{}: Slicer's Sequences module recognises sequence metafiles by the name *.seq.mha", cmd.out.string());
  ProgressBar bar("frames", cmd.progress);
  const session::ExportSummary summary =
      session::export_plus_sequence(session, cmd.out, [&](std::size_t done, std::size_t total) { bar.update(done, total); });
  bar.finish();
  if (summary.timestamps_nudged > 0)
    node::log().warn("{} frames came less than 1 ms after the one before; their Timestamp was moved to 1 ms after it "
               "(Slicer keys frames by the millisecond)",
               summary.timestamps_nudged);
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(cmd.out, ec);
  node::log().info("wrote {}: {} frames of {} x {} ({:.0f} MB); in 3D Slicer with the SlicerIGSIO extension: File > Add Data",
             cmd.out.string(), session.frames.size(), summary.cols, summary.rows,
             ec ? 0.0 : static_cast<double>(bytes) / 1e6);
  return 0;
}

}  // namespace evar::app
