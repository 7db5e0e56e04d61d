#include "recording_journal.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <array>
#include <cstring>
#include <fstream>

#include "csv_table.hpp"
#include "evar/base/atomic_file.hpp"
#include "evar/base/input_error.hpp"
#include "evar/base/unique_fd.hpp"
#include "evar/geometry/image_header.hpp"
#include "evar/geometry/json_fields.hpp"

namespace evar::session::recording {

std::string journal_frame_row(const FrameRecord& r, const Frame& f) {
  return std::to_string(r.frame) + "," + std::to_string(r.timestamp_ns) + "," + r.source + "," + r.file.generic_string() +
         "," + std::to_string(f.width) + "," + std::to_string(f.height) + "," + (f.device_clock ? "1" : "0") + "," +
         std::to_string(f.device_time_ns) + "," + std::to_string(ns_of(f.host_arrival)) + "\n";
}

std::string journal_carm_row(const CArmState& s) {
  using detail::exact;
  return std::to_string(s.device_time_ns) + "," + std::to_string(ns_of(s.host_arrival)) + "," + exact(s.primary_deg) + "," +
         exact(s.secondary_deg) + "," + exact(s.sid_mm) + "," + exact(s.sod_mm) + "," + exact(s.table_mm[0]) + "," +
         exact(s.table_mm[1]) + "," + exact(s.table_mm[2]) + "," + (s.fluoro_on ? "1" : "0") + "," + (s.moving ? "1" : "0") +
         "," + std::to_string(s.zoom_mode) + "\n";
}

void write_json_file(const fs::path& file, const nlohmann::ordered_json& j, base::Durability durability) {
  base::write_file_atomically(file, j.dump(2) + "\n", durability);
}

RecordingSettings read_settings(const fs::path& file) {
  using geometry::detail::bad_field;
  using geometry::detail::member;
  const nlohmann::json j = geometry::detail::parse_json_file(file);
  if (!j.is_object()) bad_field(file, "top level", "expected a JSON object");
  if (member(file, j, "format", "format") != kJournalFormat) bad_field(file, "format", std::string("expected \"") + kJournalFormat + "\"");
  if (member(file, j, "version", "version") != 1) bad_field(file, "version", "unsupported (this build reads version 1)");
  RecordingSettings s;
  const auto& m = member(file, j, "registration", "registration");
  if (!m.is_array() || m.size() != 4) bad_field(file, "registration", "expected 4 rows of 4 numbers");
  for (int r = 0; r < 4; ++r)
    s.ct_to_carm.row(r) =
        geometry::detail::number_array(file, m[static_cast<std::size_t>(r)], "registration[" + std::to_string(r) + "]", 4).transpose();
  s.device_thickness_mm =
      geometry::detail::number_field(file, member(file, j, "device_thickness_mm", "device_thickness_mm"), "device_thickness_mm", 0.0, 15.0, "mm");
  s.pixel_spacing_mm =
      geometry::detail::number_field(file, member(file, j, "pixel_spacing_mm", "pixel_spacing_mm"), "pixel_spacing_mm", 1e-9, 10.0, "mm");
  if (j.contains("video_mapping") || j.contains("zoom_modes")) {
    const Eigen::VectorXd d = geometry::detail::number_array(file, member(file, j, "detector_px", "detector_px"), "detector_px", 2);
    s.detector_px = {static_cast<int>(d(0)), static_cast<int>(d(1))};
  }
  if (j.contains("video_mapping")) s.video_mapping = geometry::parse_video_mapping(j["video_mapping"], file, "video_mapping.");
  if (j.contains("zoom_modes")) {
    s.zoom_modes = geometry::parse_zoom_modes(j["zoom_modes"], {s.detector_px.first, s.detector_px.second, s.pixel_spacing_mm,
                                                                s.pixel_spacing_mm}, file);
    if (j.contains("zoom_mode")) {
      const auto& m = j["zoom_mode"];
      if (!m.is_number_integer() || !geometry::find_zoom_mode(s.zoom_modes, m.get<int>()))
        bad_field(file, "zoom_mode", "must be the number of one of zoom_modes, found " + m.dump());
      s.zoom_mode = m.get<int>();
    }
  } else if (s.video_mapping) {
    if (const auto problem = geometry::video_mapping_fit_problem(*s.video_mapping, s.detector_px.first, s.detector_px.second);
        !problem.empty())
      bad_field(file, "video_mapping", problem);
  }
  return s;
}

bool whole_png(const fs::path& file, int cols, int rows) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return false;
  std::string head(64, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  try {
    const geometry::ImageHeader h = geometry::read_image_header(head, file.string());
    if (h.format != "PNG" || h.width != cols || h.height != rows) return false;
  } catch (const base::InputError&) {
    return false;
  }
  static constexpr unsigned char kIend[12] = {0, 0, 0, 0, 'I', 'E', 'N', 'D', 0xAE, 0x42, 0x60, 0x82};
  std::array<char, 12> tail{};
  in.clear();
  in.seekg(-12, std::ios::end);
  in.read(tail.data(), static_cast<std::streamsize>(tail.size()));
  return in.gcount() == 12 && std::memcmp(tail.data(), kIend, sizeof kIend) == 0;
}

void sync_session_files(const fs::path& dir) {
  if (base::sync_filesystem_of(dir)) return;  // the frames too, in one call
  for (const fs::path& p : {dir / "session.json", dir / "carm.csv", dir / "frames" / "index.csv",
                            dir / "record_report.json", dir / "frames", dir}) {
    const base::UniqueFd fd(::open(p.c_str(), O_RDONLY | O_CLOEXEC));
    if (!fd) continue;  // a file the session does not have
    ::fsync(fd.get());
  }
}

}  // namespace evar::session::recording
