#include <algorithm>
#include <limits>

#include "recording_journal.hpp"

namespace evar::session {

namespace recording {

CArmSample sample_of(const CArmState& s, std::int64_t timestamp_ns) {
  CArmSample c;
  static_cast<acquisition::CArmPose&>(c) = s;
  c.timestamp_ns = timestamp_ns;
  return c;
}

void map_frames_offline(const std::vector<std::pair<std::int64_t, acquisition::ClockPair>>& device_clock_frames,
                        std::vector<FrameRecord>& frames) {
  if (device_clock_frames.empty()) return;
  std::vector<acquisition::ClockPair> pairs;
  pairs.reserve(device_clock_frames.size());
  for (const auto& [frame, pair] : device_clock_frames) pairs.push_back(pair);
  const std::vector<std::int64_t> host_ns = acquisition::device_times_on_host(pairs);
  std::size_t k = 0;
  std::int64_t last = std::numeric_limits<std::int64_t>::min();
  for (FrameRecord& r : frames) {
    while (k < device_clock_frames.size() && device_clock_frames[k].first < r.frame) ++k;
    if (k < device_clock_frames.size() && device_clock_frames[k].first == r.frame) r.timestamp_ns = host_ns[k];
    r.timestamp_ns = std::max(r.timestamp_ns, last);
    last = r.timestamp_ns;
  }
}

Session assemble(const fs::path& out, const RecordingSettings& settings, const RecordedStreams& streams,
                 std::uint64_t& dropped, std::uint64_t& zoom_unlisted) {
  Session s;
  s.directory = out;
  s.scene = "patient/scene.json";
  s.ct_to_carm = settings.ct_to_carm;
  s.device_thickness_mm = settings.device_thickness_mm;
  s.frames = streams.frames;
  map_frames_offline(streams.device_clock_frames, s.frames);
  s.zoom_modes = settings.zoom_modes;
  for (CArmSample c : carm_on_host_clock(streams.states)) {
    if (!carm_sample_problem(c).empty()) {
      ++dropped;
      continue;
    }
    if (s.zoom_modes.empty()) {
      if (c.zoom_mode != 0) {
        c.zoom_mode = 0;  // a mode no list describes: the frames are taken as the detector's
        ++zoom_unlisted;
      }
    } else {
      // As the node decides (node/src/frame_field.cpp): the fixed mode wins; a link that says
      // none leaves the only mode listed. A mode the list lacks is kept as said: its frames
      // have no known field (session::zoom_known), rather than the mode before's.
      if (settings.zoom_mode != 0) c.zoom_mode = settings.zoom_mode;
      else if (c.zoom_mode == 0 && s.zoom_modes.size() == 1) c.zoom_mode = s.zoom_modes.front().number;
      if (!geometry::find_zoom_mode(s.zoom_modes, c.zoom_mode)) ++zoom_unlisted;
    }
    s.carm.push_back(c);
  }
  if (settings.video_mapping || !settings.zoom_modes.empty()) {
    s.detector = {settings.detector_px.first, settings.detector_px.second, settings.pixel_spacing_mm, settings.pixel_spacing_mm};
    s.video_mapping = settings.video_mapping;
  } else if (streams.size) {
    s.detector = {streams.size->first, streams.size->second, settings.pixel_spacing_mm, settings.pixel_spacing_mm};
  }
  return s;
}

}  // namespace recording

std::vector<CArmSample> carm_on_host_clock(const std::vector<acquisition::CArmState>& states) {
  std::vector<acquisition::ClockPair> pairs;
  pairs.reserve(states.size());
  for (const acquisition::CArmState& s : states) pairs.push_back({s.device_time_ns, recording::ns_of(s.host_arrival)});
  const std::vector<std::int64_t> host_ns = acquisition::device_times_on_host(pairs);
  std::vector<CArmSample> out;
  out.reserve(states.size());
  for (std::size_t i = 0; i < states.size(); ++i) out.push_back(recording::sample_of(states[i], host_ns[i]));
  return out;
}

}  // namespace evar::session
