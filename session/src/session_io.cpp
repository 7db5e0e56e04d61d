#include "evar/session/session.hpp"

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <fstream>
#include <functional>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "csv_table.hpp"
#include "evar/base/atomic_file.hpp"
#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/image_file.hpp"
#include "evar/geometry/image_header.hpp"
#include "evar/base/input_error.hpp"
#include "evar/base/input_file.hpp"
#include "evar/geometry/json_fields.hpp"
#include "evar/geometry/video_frame.hpp"

namespace evar::session {

namespace {

namespace fs = std::filesystem;
using detail::CutLastLine;
using detail::exact;
using detail::fail;
using detail::first_line_is;
using detail::flag;
using detail::for_each_row;
using detail::limited;
using detail::number;
using detail::quote;

constexpr const char* kFormat = "evarnode-session";
constexpr int kVersion = 1;
constexpr const char* kTruthRegistration = "truth/registration.json";
constexpr const char* kFramesHeader = "frame,timestamp_ns,source,file";
constexpr const char* kOstiaHeader = "frame,label,u_px,v_px";
constexpr const char* kCArmHeader =
    "timestamp_ns,primary_deg,secondary_deg,sid_mm,sod_mm,table_x_mm,table_y_mm,table_z_mm,fluoro_on,moving";
constexpr const char* kCArmZoomHeader =
    "timestamp_ns,primary_deg,secondary_deg,sid_mm,sod_mm,table_x_mm,table_y_mm,table_z_mm,fluoro_on,moving,zoom_mode";
constexpr int kMaxDetectorSidePx = 16384;

}  // namespace

std::string zoom_modes_problem(const Session& s) {
  for (std::size_t k = 0; k < s.zoom_modes.size(); ++k) {
    const geometry::ZoomMode& z = s.zoom_modes[k];
    const std::string which = "zoom mode " + std::to_string(z.number);
    if (const auto p = geometry::zoom_mode_problem(z, s.detector); !p.empty())
      return "zoom_modes[" + std::to_string(k) + "]." + p;
    if (const auto m = geometry::frame_mapping(s.video_mapping, z))
      if (const auto p = geometry::video_mapping_fit_problem(*m, z.cols, z.rows); !p.empty())
        return "video_mapping: does not fit " + which + ": " + p;
    const auto size = geometry::frame_size_px(s.video_mapping, z), first = geometry::frame_size_px(s.video_mapping, s.zoom_modes.front());
    if (size != first)
      return "zoom_modes: " + which + "'s frames are " + std::to_string(size.first) + " x " + std::to_string(size.second) +
             ", zoom mode " + std::to_string(s.zoom_modes.front().number) + "'s " + std::to_string(first.first) + " x " +
             std::to_string(first.second) + "; a session's frames share one size (give the video mapping they are shown through)";
  }
  return "";
}

namespace {

// "" unless a sample names a zoom mode in a session that lists none. With zoom modes listed,
// a sample may name one the list lacks (or 0: the link said none): a recording keeps what
// the C-arm said, and the frames in force then have no known field (zoom_mode_of is null).
std::string zoom_sample_problem(const Session& s, const CArmSample& c) {
  if (s.zoom_modes.empty() && c.zoom_mode != 0)
    return "zoom_mode: " + std::to_string(c.zoom_mode) + ", but session.json lists no zoom_modes";
  return "";
}

// What read_detector_frame and export say of a frame taken in a mode the session does not list.
std::string unknown_zoom(const Session& s, std::size_t index, const CArmSample& c) {
  return "frame " + std::to_string(s.frames[index].frame) + " was taken in zoom mode " + std::to_string(c.zoom_mode) +
         ", which session.json's zoom_modes do not list: its pixels are unknown";
}

bool plain_name(const std::string& s) {
  if (s.empty()) return false;
  for (const char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.')) return false;
  return true;
}

// What is wrong with a path a session names ("" when nothing): it must be relative, have no
// ".." component (a..b.png is a fine name) and no character that would break a CSV row.
std::string relative_path_problem(const std::string& p) {
  if (p.empty()) return "empty";
  if (fs::path(p).is_absolute()) return "absolute";
  for (const auto& part : fs::path(p))
    if (part == "..") return "has a '..' component";
  for (const char c : p)
    if (c == ',' || static_cast<unsigned char>(c) < 0x20 || c == 0x7f) return "holds a comma or a control character";
  return {};
}

// Whether `full` stays inside the directory whose canonical form is `root` once symbolic
// links are followed: a link in the session must not lead a reader out of it.
bool resolves_inside(const fs::path& root, const fs::path& full) {
  std::error_code ec;
  const fs::path real = fs::weakly_canonical(full, ec);
  if (ec) return false;
  const auto [r, f] = std::mismatch(root.begin(), root.end(), real.begin(), real.end());
  return r == root.end();
}

fs::path canonical_root(const fs::path& directory) {
  std::error_code ec;
  fs::path root = fs::weakly_canonical(directory, ec);
  if (ec) throw base::InputError(directory.string() + ": cannot resolve the session directory (" + ec.message() + ")");
  return root;
}

std::string timestamp_problem(std::int64_t t) {
  if (t < 0 || t >= kMaxTimestampNs)
    return "timestamp_ns: " + std::to_string(t) + " is outside 0 to 2^62 ns";
  return {};
}

std::string frame_order_problem(const FrameRecord& previous, const FrameRecord& r) {
  if (r.frame <= previous.frame) return "frame: " + std::to_string(r.frame) + " does not increase";
  if (r.timestamp_ns < previous.timestamp_ns) return "timestamp_ns: goes back in time";
  return {};
}

std::string detector_problem(const geometry::DetectorSpec& d) {
  if (d.cols < 1 || d.cols > kMaxDetectorSidePx) return "detector.cols: expected an integer from 1 to 16384";
  if (d.rows < 1 || d.rows > kMaxDetectorSidePx) return "detector.rows: expected an integer from 1 to 16384";
  if (std::int64_t{d.cols} * d.rows > geometry::kMaxImagePixels)
    return "detector: " + std::to_string(d.cols) + " x " + std::to_string(d.rows) + " pixels; at most " +
           std::to_string(geometry::kMaxImagePixels) + " in all";
  if (!(std::isfinite(d.row_spacing_mm) && d.row_spacing_mm > 0.0)) return "detector.row_spacing_mm: expected a positive number";
  if (!(std::isfinite(d.col_spacing_mm) && d.col_spacing_mm > 0.0)) return "detector.col_spacing_mm: expected a positive number";
  return {};
}

std::string ostium_problem(const OstiumTruth& o) {
  if (!plain_name(o.label)) return "label: " + quote(o.label) + " (letters, digits, '_', '-', '.')";
  if (!std::isfinite(o.pixel.x())) return "u_px: " + exact(o.pixel.x()) + " is not finite";
  if (!std::isfinite(o.pixel.y())) return "v_px: " + exact(o.pixel.y()) + " is not finite";
  return {};
}

bool has_frame(const std::vector<FrameRecord>& frames, std::int64_t frame) {
  const auto at = std::lower_bound(frames.begin(), frames.end(), frame,
                                   [](const FrameRecord& r, std::int64_t f) { return r.frame < f; });
  return at != frames.end() && at->frame == frame;
}

void write_text(const fs::path& file, const std::string& text) { base::write_file_atomically(file, text); }

}  // namespace

std::string frame_record_problem(const FrameRecord& r) {
  if (auto p = timestamp_problem(r.timestamp_ns); !p.empty()) return p;
  if (!plain_name(r.source)) return "source: " + quote(r.source) + " (letters, digits, '_', '-', '.')";
  if (const auto p = relative_path_problem(r.file.generic_string()); !p.empty())
    return "file: " + quote(r.file.generic_string()) + " must be a relative path inside the frames folder (" + p + ")";
  return {};
}

std::string carm_sample_problem(const CArmSample& c) {
  if (auto p = timestamp_problem(c.timestamp_ns); !p.empty()) return p;
  const std::pair<const char*, double> values[] = {{"primary_deg", c.primary_deg}, {"secondary_deg", c.secondary_deg},
                                                   {"sid_mm", c.sid_mm},           {"sod_mm", c.sod_mm},
                                                   {"table_x_mm", c.table_mm[0]}, {"table_y_mm", c.table_mm[1]},
                                                   {"table_z_mm", c.table_mm[2]}};
  for (const auto& [field, v] : values)
    if (!std::isfinite(v)) return std::string(field) + ": " + exact(v) + " is not finite";
  if (std::abs(c.primary_deg) > 180.0) return "primary_deg: " + exact(c.primary_deg) + " is outside -180 to 180";
  if (std::abs(c.secondary_deg) > 90.0) return "secondary_deg: " + exact(c.secondary_deg) + " is outside -90 to 90";
  if (!(c.sod_mm > 0.0 && c.sod_mm < c.sid_mm && c.sid_mm <= 5000.0))
    return "sid_mm, sod_mm: need 0 < SOD < SID <= 5000, found SID " + exact(c.sid_mm) + ", SOD " + exact(c.sod_mm);
  if (c.zoom_mode < 0 || c.zoom_mode > 255) return "zoom_mode: " + std::to_string(c.zoom_mode) + " is outside 0 to 255";
  return {};
}

Session read_session(const std::filesystem::path& directory) {
  Session s;
  s.directory = directory;
  const fs::path root = canonical_root(directory);
  const fs::path json_path = directory / "session.json";
  const nlohmann::json j = geometry::detail::parse_json_file(json_path);
  const auto field = [&](const char* key) -> const nlohmann::json& {
    if (!j.is_object() || !j.contains(key)) fail(json_path, 0, std::string(key) + ": missing");
    return j[key];
  };
  if (field("format") != kFormat) fail(json_path, 0, std::string("format: expected \"") + kFormat + "\"");
  if (!field("version").is_number_integer() || field("version").get<long long>() != kVersion)
    fail(json_path, 0, "version: unsupported " + limited(field("version").dump()) + " (this build reads version 1)");
  // A file the session names: relative, and inside the session once links are followed.
  const auto inside = [&](const std::string& name, const nlohmann::json& value) {
    if (!value.is_string()) fail(json_path, 0, name + ": expected a relative file name inside the session");
    const std::string p = value.get<std::string>();
    if (const auto problem = relative_path_problem(p); !problem.empty())
      fail(json_path, 0, name + ": " + quote(p) + " must be a relative file name inside the session (" + problem + ")");
    if (!resolves_inside(root, directory / p))
      fail(json_path, 0, name + ": " + quote(p) + " leads out of the session directory (a symbolic link)");
    return fs::path(p);
  };
  s.scene = inside("scene", field("scene"));
  s.ct_to_carm = geometry::read_registration(directory / inside("registration", field("registration")));
  if (!field("device_thickness_mm").is_number()) fail(json_path, 0, "device_thickness_mm: expected a number");
  s.device_thickness_mm = field("device_thickness_mm").get<double>();
  if (!(s.device_thickness_mm >= 0.0 && s.device_thickness_mm <= 15.0))
    fail(json_path, 0, "device_thickness_mm: must be 0 to 15 (mm)");
  const auto& det = field("detector");
  for (const char* key : {"cols", "rows"})
    if (!det.is_object() || !det.contains(key) || !det[key].is_number_integer() || det[key].get<long long>() <= 0 ||
        det[key].get<long long>() > kMaxDetectorSidePx)
      fail(json_path, 0, std::string("detector.") + key + ": expected an integer from 1 to 16384");
  for (const char* key : {"row_spacing_mm", "col_spacing_mm"})
    if (!det.contains(key) || !det[key].is_number()) fail(json_path, 0, std::string("detector.") + key + ": expected a positive number");
  s.detector = {det["cols"].get<int>(), det["rows"].get<int>(), det["row_spacing_mm"].get<double>(),
                det["col_spacing_mm"].get<double>()};
  if (const auto problem = detector_problem(s.detector); !problem.empty()) fail(json_path, 0, problem);
  if (j.contains("video_mapping")) s.video_mapping = geometry::parse_video_mapping(j["video_mapping"], json_path, "video_mapping.");
  if (j.contains("zoom_modes")) {
    s.zoom_modes = geometry::parse_zoom_modes(j["zoom_modes"], s.detector, json_path);
    if (const auto problem = zoom_modes_problem(s); !problem.empty()) fail(json_path, 0, problem);
  } else if (s.video_mapping) {
    if (const auto problem = geometry::video_mapping_fit_problem(*s.video_mapping, s.detector.cols, s.detector.rows);
        !problem.empty())
      fail(json_path, 0, "video_mapping: does not fit the detector: " + problem);
  }
  const auto& streams = field("streams");
  if (!streams.is_object() || !streams.contains("frames") || !streams.contains("carm"))
    fail(json_path, 0, "streams: expected {\"frames\": \"frames/index.csv\", \"carm\": \"carm.csv\"} (relative paths inside the session)");
  s.frames_index = inside("streams.frames", streams["frames"]);
  const fs::path carm_name = inside("streams.carm", streams["carm"]);

  // Frames.
  const fs::path index = directory / s.frames_index;
  for_each_row(index, kFramesHeader, 4, CutLastLine::Refuse, [&](std::size_t line, const std::vector<std::string>& f) {
    FrameRecord r;
    r.frame = number<std::int64_t>(index, line, "frame", f[0]);
    r.timestamp_ns = number<std::int64_t>(index, line, "timestamp_ns", f[1]);
    r.source = f[2];
    r.file = f[3];
    if (const auto problem = frame_record_problem(r); !problem.empty()) fail(index, line, problem);
    if (!s.frames.empty())
      if (const auto problem = frame_order_problem(s.frames.back(), r); !problem.empty()) fail(index, line, problem);
    const fs::path full = index.parent_path() / r.file;
    if (!fs::is_regular_file(full)) fail(index, line, "file: " + limited(f[3]) + " is missing");
    if (!resolves_inside(root, full)) fail(index, line, "file: " + quote(f[3]) + " leads out of the session directory (a symbolic link)");
    s.frames.push_back(std::move(r));
  });

  // C-arm geometry stream.
  const fs::path carm = directory / carm_name;
  // The zoom mode's column: with zoom modes it must be there; without, it may (all 0).
  const bool zoom_column = first_line_is(carm, kCArmZoomHeader);
  if (!s.zoom_modes.empty() && !zoom_column)
    fail(carm, 1, std::string("header: session.json lists zoom_modes, so expected '") + kCArmZoomHeader + "'");
  for_each_row(carm, zoom_column ? kCArmZoomHeader : kCArmHeader, zoom_column ? 11 : 10, CutLastLine::Refuse,
               [&](std::size_t line, const std::vector<std::string>& f) {
    CArmSample c;
    c.timestamp_ns = number<std::int64_t>(carm, line, "timestamp_ns", f[0]);
    c.primary_deg = number<double>(carm, line, "primary_deg", f[1]);
    c.secondary_deg = number<double>(carm, line, "secondary_deg", f[2]);
    c.sid_mm = number<double>(carm, line, "sid_mm", f[3]);
    c.sod_mm = number<double>(carm, line, "sod_mm", f[4]);
    for (int k = 0; k < 3; ++k)
      c.table_mm[static_cast<std::size_t>(k)] = number<double>(carm, line, k == 0 ? "table_x_mm" : k == 1 ? "table_y_mm" : "table_z_mm", f[5 + static_cast<std::size_t>(k)]);
    c.fluoro_on = flag(carm, line, "fluoro_on", f[8]);
    c.moving = flag(carm, line, "moving", f[9]);
    if (zoom_column) c.zoom_mode = number<int>(carm, line, "zoom_mode", f[10]);
    if (const auto problem = carm_sample_problem(c); !problem.empty()) fail(carm, line, problem);
    if (const auto problem = zoom_sample_problem(s, c); !problem.empty()) fail(carm, line, problem);
    if (!s.carm.empty() && c.timestamp_ns < s.carm.back().timestamp_ns) fail(carm, line, "timestamp_ns: goes back in time");
    s.carm.push_back(c);
  });

  // Ground truth (optional).
  if (j.contains("ground_truth")) {
    const auto& g = j["ground_truth"];
    SessionTruth truth;
    const auto truth_file = [&](const char* key) {
      const std::string name = std::string("ground_truth.") + key;
      if (!g.is_object() || !g.contains(key)) fail(json_path, 0, name + ": expected a relative file name inside the session");
      const fs::path p = inside(name, g[key]);
      if (!fs::is_regular_file(directory / p)) fail(json_path, 0, name + ": " + limited(p.generic_string()) + " is missing");
      return p;
    };
    truth.scene = truth_file("scene");
    truth.device = truth_file("device");
    truth.ostia_2d = truth_file("ostia_2d");
    if (g.contains("registration")) truth.ct_to_carm = geometry::read_registration(directory / truth_file("registration"));
    const fs::path ostia = directory / truth.ostia_2d;
    for_each_row(ostia, kOstiaHeader, 4, CutLastLine::Refuse, [&](std::size_t line, const std::vector<std::string>& f) {
      OstiumTruth o;
      o.frame = number<std::int64_t>(ostia, line, "frame", f[0]);
      if (!has_frame(s.frames, o.frame)) fail(ostia, line, "frame: " + std::to_string(o.frame) + " is not in the frames index");
      o.label = f[1];
      o.pixel = {number<double>(ostia, line, "u_px", f[2]), number<double>(ostia, line, "v_px", f[3])};
      if (const auto problem = ostium_problem(o); !problem.empty()) fail(ostia, line, problem);
      truth.ostia.push_back(std::move(o));
    });
    s.truth = std::move(truth);
  }
  return s;
}

cv::Mat read_session_frame(const Session& session, std::size_t index) {
  if (index >= session.frames.size()) throw std::out_of_range("read_session_frame: no frame " + std::to_string(index));
  const fs::path file = (session.directory / session.frames_index).parent_path() / session.frames[index].file;
  // Checked again here: the file may have been replaced since read_session.
  if (!resolves_inside(canonical_root(session.directory), file))
    fail(file, 0, "leads out of the session directory (a symbolic link)");
  const cv::Mat image = geometry::read_image_file(file, "PNG");
  if (image.type() != CV_16UC1) fail(file, 0, "expected a 16-bit single-channel PNG");
  if (const auto [cols, rows] = frame_size_px(session); image.cols != cols || image.rows != rows)
    fail(file, 0, std::to_string(image.cols) + " x " + std::to_string(image.rows) + " pixels, but " +
                      (session.video_mapping        ? "the video mapping's frames are "
                       : !session.zoom_modes.empty() ? "the zoom modes' frames are "
                                                     : "the detector is ") +
                      std::to_string(cols) + " x " + std::to_string(rows));
  return image;
}

cv::Mat read_detector_frame(const Session& session, std::size_t index) {
  cv::Mat frame = read_session_frame(session, index);
  const CArmSample* c = session.zoom_modes.empty() ? nullptr : carm_at(session, session.frames[index].timestamp_ns);
  const geometry::ZoomMode* zoom = c ? zoom_mode_of(session, *c) : nullptr;
  if (c && !zoom) throw base::InputError(session.directory.string() + ": " + unknown_zoom(session, index, *c));
  if (!zoom) {
    if (!session.video_mapping) return frame;
    return geometry::detector_image(frame, geometry::VideoToDetector(*session.video_mapping, session.detector.cols,
                                                                     session.detector.rows));
  }
  const auto mapping = geometry::frame_mapping(session.video_mapping, *zoom);
  if (!mapping) return frame;
  return geometry::detector_image(frame, geometry::VideoToDetector(*mapping, zoom->cols, zoom->rows));
}

std::pair<int, int> frame_size_px(const Session& session) {
  if (session.video_mapping) return {session.video_mapping->video_cols, session.video_mapping->video_rows};
  if (!session.zoom_modes.empty()) return geometry::frame_size_px(std::nullopt, session.zoom_modes.front());
  return {session.detector.cols, session.detector.rows};
}

const geometry::ZoomMode* zoom_mode_of(const Session& session, const CArmSample& sample) {
  return geometry::find_zoom_mode(session.zoom_modes, sample.zoom_mode);
}

bool zoom_known(const Session& session, const CArmSample& sample) {
  return session.zoom_modes.empty() || zoom_mode_of(session, sample) != nullptr;
}

void write_session_frame(const std::filesystem::path& directory, const FrameRecord& f, const cv::Mat& image) {
  if (image.type() != CV_16UC1) throw std::invalid_argument("write_session: frames must be CV_16UC1");
  if (const auto problem = frame_record_problem(f); !problem.empty())
    throw std::invalid_argument("write_session: frame " + std::to_string(f.frame) + ": " + problem);
  const fs::path out = directory / "frames" / f.file;
  fs::create_directories(out.parent_path());
  // Not synced one by one: a recording syncs its frames' folder when it finishes.
  geometry::write_image_file(out, image, {".png", {cv::IMWRITE_PNG_COMPRESSION, 1}, base::Durability::Deferred});
}

void write_session_files(const std::filesystem::path& directory, const Session& session) {
  // Everything is checked before anything is written, by the reader's own rules.
  const auto refuse = [](const std::string& what) { throw std::invalid_argument("write_session: " + what); };
  if (const auto problem = detector_problem(session.detector); !problem.empty()) refuse(problem);
  if (!session.zoom_modes.empty()) {
    if (const auto problem = zoom_modes_problem(session); !problem.empty()) refuse(problem);
  } else if (session.video_mapping) {
    if (const auto problem =
            geometry::video_mapping_fit_problem(*session.video_mapping, session.detector.cols, session.detector.rows);
        !problem.empty())
      refuse("video_mapping: does not fit the detector: " + problem);
  }
  if (!(session.device_thickness_mm >= 0.0 && session.device_thickness_mm <= 15.0))
    refuse("device_thickness_mm: must be 0 to 15 (mm)");
  if (const auto problem = relative_path_problem(session.scene.generic_string()); !problem.empty())
    refuse("scene: " + quote(session.scene.generic_string()) + " must be a relative file name inside the session (" + problem + ")");
  for (std::size_t i = 0; i < session.frames.size(); ++i) {
    const auto& f = session.frames[i];
    const std::string which = "frame " + std::to_string(f.frame) + ": ";
    if (const auto problem = frame_record_problem(f); !problem.empty()) refuse(which + problem);
    if (i > 0)
      if (const auto problem = frame_order_problem(session.frames[i - 1], f); !problem.empty()) refuse(which + problem);
    if (!fs::is_regular_file(directory / "frames" / f.file)) refuse(which + "has no image written");
  }
  for (std::size_t i = 0; i < session.carm.size(); ++i) {
    const auto& c = session.carm[i];
    const std::string which = "C-arm sample " + std::to_string(i) + ": ";
    if (const auto problem = carm_sample_problem(c); !problem.empty()) refuse(which + problem);
    if (const auto problem = zoom_sample_problem(session, c); !problem.empty()) refuse(which + problem);
    if (i > 0 && c.timestamp_ns < session.carm[i - 1].timestamp_ns) refuse(which + "timestamp_ns: goes back in time");
  }
  if (session.truth) {
    const SessionTruth& t = *session.truth;
    for (const fs::path& p : {t.scene, t.device, t.ostia_2d})
      if (const auto problem = relative_path_problem(p.generic_string()); !problem.empty())
        refuse("ground truth: " + quote(p.generic_string()) + " must be a relative file name inside the session (" + problem + ")");
    for (const fs::path& p : {t.scene, t.device})
      if (!fs::is_regular_file(directory / p)) refuse("ground truth " + quote(p.generic_string()) + " is missing");
    for (const auto& o : t.ostia) {
      if (const auto problem = ostium_problem(o); !problem.empty()) refuse("ostium of frame " + std::to_string(o.frame) + ": " + problem);
      if (!has_frame(session.frames, o.frame))
        refuse("ostium for frame " + std::to_string(o.frame) + ", which is not in the session");
    }
  }

  fs::create_directories(directory / "frames");
  // A registration is checked by its reader: written, then read back.
  const auto write_registration = [&](const fs::path& file, const Eigen::Matrix4d& M, const std::string& what) {
    nlohmann::json rows = nlohmann::json::array();
    for (int r = 0; r < 4; ++r) rows.push_back({M(r, 0), M(r, 1), M(r, 2), M(r, 3)});
    fs::create_directories(file.parent_path());
    write_text(file, nlohmann::json{{"matrix", rows}}.dump(2) + "\n");
    try {
      geometry::read_registration(file);
    } catch (const base::InputError& e) {
      refuse(what + ": " + e.what());
    }
  };
  write_registration(directory / "registration.json", session.ct_to_carm, "registration");
  if (session.truth && session.truth->ct_to_carm)
    write_registration(directory / kTruthRegistration, *session.truth->ct_to_carm, "ground truth registration");
  std::string index = std::string(kFramesHeader) + "\n";
  for (const auto& f : session.frames)
    index += std::to_string(f.frame) + "," + std::to_string(f.timestamp_ns) + "," + f.source + "," + f.file.generic_string() + "\n";
  write_text(directory / "frames" / "index.csv", index);
  const bool zoom_column = !session.zoom_modes.empty();
  std::string carm = std::string(zoom_column ? kCArmZoomHeader : kCArmHeader) + "\n";
  for (const auto& c : session.carm)
    carm += std::to_string(c.timestamp_ns) + "," + exact(c.primary_deg) + "," + exact(c.secondary_deg) + "," + exact(c.sid_mm) +
            "," + exact(c.sod_mm) + "," + exact(c.table_mm[0]) + "," + exact(c.table_mm[1]) + "," + exact(c.table_mm[2]) +
            "," + (c.fluoro_on ? "1" : "0") + "," + (c.moving ? "1" : "0") +
            (zoom_column ? "," + std::to_string(c.zoom_mode) : std::string()) + "\n";
  write_text(directory / "carm.csv", carm);
  const geometry::DetectorSpec& d = session.detector;
  nlohmann::ordered_json j{{"format", kFormat},
                           {"version", kVersion},
                           {"scene", session.scene.generic_string()},
                           {"registration", "registration.json"},
                           {"device_thickness_mm", session.device_thickness_mm},
                           {"detector",
                            {{"cols", d.cols}, {"rows", d.rows}, {"row_spacing_mm", d.row_spacing_mm}, {"col_spacing_mm", d.col_spacing_mm}}},
                           {"streams", {{"frames", "frames/index.csv"}, {"carm", "carm.csv"}}}};
  if (session.video_mapping)
    j["video_mapping"] = nlohmann::ordered_json::parse(geometry::video_mapping_json(*session.video_mapping).dump());
  if (!session.zoom_modes.empty())
    j["zoom_modes"] = nlohmann::ordered_json::parse(geometry::zoom_modes_json(session.zoom_modes).dump());
  if (session.truth) {
    const SessionTruth& t = *session.truth;
    std::string ostia = std::string(kOstiaHeader) + "\n";
    for (const auto& o : t.ostia)
      ostia += std::to_string(o.frame) + "," + o.label + "," + exact(o.pixel.x()) + "," + exact(o.pixel.y()) + "\n";
    fs::create_directories((directory / t.ostia_2d).parent_path());
    write_text(directory / t.ostia_2d, ostia);
    j["ground_truth"] = {{"scene", t.scene.generic_string()}, {"device", t.device.generic_string()}, {"ostia_2d", t.ostia_2d.generic_string()}};
    if (t.ct_to_carm) j["ground_truth"]["registration"] = kTruthRegistration;
  }
  // session.json last: a reader never finds it naming files not yet written.
  write_text(directory / "session.json", j.dump(2) + "\n");
}

void write_session(const std::filesystem::path& directory, const Session& session, const std::vector<cv::Mat>& images) {
  if (images.size() != session.frames.size())
    throw std::invalid_argument("write_session: one image per frame record is required");
  for (const auto& image : images)
    if (const auto [cols, rows] = frame_size_px(session); image.cols != cols || image.rows != rows)
      throw std::invalid_argument(std::string("write_session: every image must have the ") +
                                  (session.video_mapping ? "video mapping's" : "detector's") + " size");
  for (std::size_t i = 0; i < session.frames.size(); ++i) write_session_frame(directory, session.frames[i], images[i]);
  write_session_files(directory, session);
}

geometry::CArmView view_of(const Session& session, const CArmSample& c) {
  if (const geometry::ZoomMode* zoom = zoom_mode_of(session, c))
    return geometry::zoom_view(session.detector, *zoom, c.primary_deg, c.secondary_deg, c.sid_mm, c.sod_mm);
  if (!session.zoom_modes.empty())
    throw std::invalid_argument("view_of: zoom mode " + std::to_string(c.zoom_mode) +
                                " is not one of the session's zoom_modes (check zoom_known first)");
  return geometry::view_of(session.detector, c.primary_deg, c.secondary_deg, c.sid_mm, c.sod_mm);
}

Eigen::Matrix4d patient_to_carm(const Session& session, const CArmSample& c) {
  return geometry::patient_to_carm(session.ct_to_carm, {c.table_mm[0], c.table_mm[1], c.table_mm[2]});
}

const CArmSample* carm_at(const Session& session, std::int64_t timestamp_ns) {
  if (session.carm.empty()) return nullptr;
  const auto after = std::upper_bound(session.carm.begin(), session.carm.end(), timestamp_ns,
                                      [](std::int64_t t, const CArmSample& c) { return t < c.timestamp_ns; });
  return after == session.carm.begin() ? &session.carm.front() : &*(after - 1);
}

ExportSummary export_plus_sequence(const Session& session, const std::filesystem::path& mha,
                                   const std::function<void(std::size_t, std::size_t)>& progress) {
  if (session.frames.empty()) throw std::invalid_argument("export_plus_sequence: the session has no frames");
  // Every file the export reads is inside the session directory (read_session sees to it),
  // so an output anywhere inside could overwrite one of them.
  if (!session.directory.empty() && resolves_inside(canonical_root(session.directory), mha))
    throw std::invalid_argument(mha.string() + ": is inside the session directory " + session.directory.string() +
                                ", among the files the export reads; write it outside the session");
  for (const auto& f : session.frames)
    if (const auto problem = frame_record_problem(f); !problem.empty())
      throw std::invalid_argument("export_plus_sequence: frame " + std::to_string(f.frame) + ": " + problem);
  // The frames are streamed one at a time (an hour's recording does not fit in memory);
  // Detector images (read_detector_frame): a video-out session's frames are resampled, so
  // the sequence's pixels have the detector's spacing.
  // With zoom modes, the image of the modes the frames were taken in: one size and spacing,
  // as a sequence has.
  geometry::DetectorSpec image = session.detector;
  const geometry::ZoomMode* first_zoom = nullptr;
  for (std::size_t i = 0; i < session.frames.size(); ++i) {
    const auto& f = session.frames[i];
    if (session.zoom_modes.empty()) break;
    const CArmSample* c = carm_at(session, f.timestamp_ns);
    if (!c)
      throw base::InputError(session.directory.string() + ": frame " + std::to_string(f.frame) +
                             " has no C-arm sample, so no zoom mode: its pixels are unknown (carm.csv is empty)");
    const geometry::ZoomMode* z = zoom_mode_of(session, *c);
    if (!z) throw base::InputError(session.directory.string() + ": " + unknown_zoom(session, i, *c));
    if (!first_zoom) {
      first_zoom = z;
      image = geometry::image_detector(*z);
    } else if (z->cols != image.cols || z->rows != image.rows || z->col_spacing_mm != image.col_spacing_mm ||
               z->row_spacing_mm != image.row_spacing_mm) {
      throw base::InputError(session.directory.string() + ": frame " + std::to_string(f.frame) + " was taken in zoom mode " +
                             std::to_string(z->number) + " (\"" + z->name + "\"), whose pixels differ from zoom mode " +
                             std::to_string(first_zoom->number) + "'s; a PLUS sequence has one pixel size: export the "
                             "frames of each mode from a session of their own");
    }
  }
  const int W = image.cols, H = image.rows;
  const auto spacing = [](double mm) { return std::isfinite(mm) && mm > 0.0 ? exact(mm) : std::string("1"); };
  // PLUS's own header, in its order (its writer keeps the fields in a sorted map). X-ray
  // frames are 2-D grey images like B-mode ones: type BRIGHTNESS, orientation MF (row 0 at
  // the top, as stored), which PLUS reads without reorienting.
  std::ostringstream h;
  h << "ObjectType = Image\nNDims = 3\nAnatomicalOrientation = RAI\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
    << "CenterOfRotation = 0 0 0\nCompressedData = False\nDimSize = " << W << " " << H << " " << session.frames.size()
    << "\nElementNumberOfChannels = 1\nElementSpacing = " << spacing(image.col_spacing_mm) << " "
    << spacing(image.row_spacing_mm) << " 1\nElementType = MET_USHORT\nKinds = domain domain list\n"
    << "Offset = 0 0 0\nTransformMatrix = 1 0 0 0 1 0 0 0 1\nUltrasoundImageOrientation = MF\n"
    << "UltrasoundImageType = BRIGHTNESS\n";
  ExportSummary summary;
  summary.frames = session.frames.size();
  summary.cols = W;
  summary.rows = H;
  // Slicer's importer keys each frame by its Timestamp printed with 3 decimals, so frames
  // less than 1 ms apart would collapse into one: whole milliseconds, each at least 1 ms
  // after the one before (differences cannot overflow: timestamps are below 2^62).
  const std::int64_t t0 = session.frames.front().timestamp_ns;
  std::int64_t previous_ms = -1;
  char name[32], stamp[48];
  for (std::size_t i = 0; i < session.frames.size(); ++i) {
    const auto& f = session.frames[i];
    std::int64_t ms = (f.timestamp_ns - t0 + 500'000) / 1'000'000;
    if (ms <= previous_ms) {
      ms = previous_ms + 1;
      ++summary.timestamps_nudged;
    }
    previous_ms = ms;
    std::snprintf(name, sizeof name, "Seq_Frame%04zu_", i);
    std::snprintf(stamp, sizeof stamp, "%lld.%03lld", static_cast<long long>(ms / 1000), static_cast<long long>(ms % 1000));
    h << name << "FrameNumber = " << f.frame << "\n";
    h << name << "Timestamp = " << stamp << "\n";
    h << name << "ImageStatus = OK\n";
    h << name << "Source = " << f.source << "\n";
    if (const CArmSample* c = carm_at(session, f.timestamp_ns)) {
      h << name << "PrimaryAngleDeg = " << exact(c->primary_deg) << "\n";
      h << name << "SecondaryAngleDeg = " << exact(c->secondary_deg) << "\n";
      h << name << "SidMm = " << exact(c->sid_mm) << "\n";
      h << name << "SodMm = " << exact(c->sod_mm) << "\n";
      h << name << "CArmMoving = " << (c->moving ? 1 : 0) << "\n";
    }
  }
  h << "ElementDataFile = LOCAL\n";

  // Through an AtomicFile: a failure (a bad frame half-way) leaves no partial sequence.
  base::AtomicFile out(mha);
  out.write(h.str());
  std::vector<char> row(static_cast<std::size_t>(W) * 2);
  for (std::size_t i = 0; i < session.frames.size(); ++i) {
    const cv::Mat image = read_detector_frame(session, i);
    if (image.cols != W || image.rows != H)  // checked above; the files may have changed since
      throw base::InputError(session.directory.string() + ": frame " + std::to_string(session.frames[i].frame) + " is " +
                             std::to_string(image.cols) + " x " + std::to_string(image.rows) + " detector pixels, the sequence " +
                             std::to_string(W) + " x " + std::to_string(H));
    for (int r = 0; r < H; ++r) {
      const auto* px = image.ptr<std::uint16_t>(r);
      for (int c = 0; c < W; ++c) {  // little endian, whatever the host
        row[2 * static_cast<std::size_t>(c)] = static_cast<char>(px[c] & 0xff);
        row[2 * static_cast<std::size_t>(c) + 1] = static_cast<char>(px[c] >> 8);
      }
      out.write({row.data(), row.size()});
    }
    if (progress) progress(i + 1, session.frames.size());
  }
  out.commit();
  return summary;
}

}  // namespace evar::session
