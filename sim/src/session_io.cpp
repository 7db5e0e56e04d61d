#include "evar/sim/session.hpp"

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <cmath>
#include <fstream>
#include <functional>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/image_header.hpp"
#include "evar/geometry/input_error.hpp"
#include "evar/geometry/image_file.hpp"
#include "evar/geometry/input_file.hpp"
#include "evar/geometry/json_fields.hpp"

namespace evar::sim {

namespace {

namespace fs = std::filesystem;
using geometry::InputError;

constexpr const char* kFormat = "evarnode-session";
constexpr int kVersion = 1;
constexpr const char* kFramesHeader = "frame,timestamp_ns,source,file";
constexpr const char* kOstiaHeader = "frame,label,u_px,v_px";
constexpr const char* kCArmHeader =
    "timestamp_ns,primary_deg,secondary_deg,sid_mm,sod_mm,table_x_mm,table_y_mm,table_z_mm,fluoro_on,moving";

[[noreturn]] void fail(const fs::path& file, std::size_t line, const std::string& what) {
  throw InputError(file.string() + (line ? ":" + std::to_string(line) : std::string()) + ": " + what);
}

// Calls row(line number, fields) for every non-empty line after the header, checking the
// header and the field count; lines end in LF or CRLF.
template <class Row>
void for_each_row(const fs::path& file, const char* header, std::size_t fields, Row row) {
  const std::string text = geometry::read_input_file(file, geometry::kTableLimit);
  std::size_t start = 0, line = 0;
  while (start < text.size() || line == 0) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string content = text.substr(start, end - start);
    if (!content.empty() && content.back() == '\r') content.pop_back();
    start = end + 1;
    if (++line == 1) {
      if (content != header) fail(file, 1, std::string("header: expected '") + header + "'");
      continue;
    }
    if (content.empty()) continue;
    std::vector<std::string> f;
    for (std::size_t from = 0;;) {
      const std::size_t comma = content.find(',', from);
      f.push_back(content.substr(from, comma == std::string::npos ? std::string::npos : comma - from));
      if (comma == std::string::npos) break;
      from = comma + 1;
    }
    if (f.size() != fields)
      fail(file, line, "expected " + std::to_string(fields) + " fields, found " + std::to_string(f.size()));
    row(line, f);
  }
}

template <class T>
T number(const fs::path& file, std::size_t line, const char* field, const std::string& text) {
  T value{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty())
    fail(file, line, std::string(field) + ": '" + text + "' is not a number");
  if constexpr (std::is_floating_point_v<T>)
    if (!std::isfinite(value)) fail(file, line, std::string(field) + ": '" + text + "' is not finite");
  return value;
}

bool flag(const fs::path& file, std::size_t line, const char* field, const std::string& text) {
  if (text == "0") return false;
  if (text == "1") return true;
  fail(file, line, std::string(field) + ": '" + text + "' (expected 0 or 1)");
}

bool plain_name(const std::string& s) {
  if (s.empty()) return false;
  for (const char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.')) return false;
  return true;
}

// A path a session may name: relative, inside the session, not empty.
bool inside_path(const std::string& p) {
  return !p.empty() && !fs::path(p).is_absolute() && p.find("..") == std::string::npos;
}

// The shortest text that reads back to the same double.
std::string exact(double v) {
  char buf[64];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  if (ec != std::errc()) throw std::runtime_error("cannot format a number");
  return std::string(buf, end);
}

void write_text(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error(file.string() + ": cannot write");
}

}  // namespace

Session read_session(const std::filesystem::path& directory) {
  Session s;
  s.directory = directory;
  const fs::path json_path = directory / "session.json";
  const nlohmann::json j = geometry::detail::parse_json_file(json_path);
  const auto field = [&](const char* key) -> const nlohmann::json& {
    if (!j.is_object() || !j.contains(key)) fail(json_path, 0, std::string(key) + ": missing");
    return j[key];
  };
  if (field("format") != kFormat) fail(json_path, 0, std::string("format: expected \"") + kFormat + "\"");
  if (!field("version").is_number_integer() || field("version").get<long long>() != kVersion)
    fail(json_path, 0, "version: unsupported " + field("version").dump() + " (this build reads version 1)");
  const auto path_field = [&](const char* key) {
    if (!field(key).is_string() || !inside_path(field(key).get<std::string>()))
      fail(json_path, 0, std::string(key) + ": expected a relative file name inside the session");
    return fs::path(field(key).get<std::string>());
  };
  s.scene = path_field("scene");
  s.ct_to_carm = geometry::read_registration(directory / path_field("registration"));
  if (!field("device_thickness_mm").is_number()) fail(json_path, 0, "device_thickness_mm: expected a number");
  s.device_thickness_mm = field("device_thickness_mm").get<double>();
  if (!(s.device_thickness_mm >= 0.0 && s.device_thickness_mm <= 15.0))
    fail(json_path, 0, "device_thickness_mm: must be 0 to 15 (mm)");
  const auto& det = field("detector");
  const auto positive = [&](const char* key) {
    if (!det.is_object() || !det.contains(key) || !det[key].is_number() || !(det[key].get<double>() > 0.0))
      fail(json_path, 0, std::string("detector.") + key + ": expected a positive number");
    return det[key].get<double>();
  };
  for (const char* key : {"cols", "rows"})
    if (!det.is_object() || !det.contains(key) || !det[key].is_number_integer() || det[key].get<long long>() <= 0 ||
        det[key].get<long long>() > 16384)
      fail(json_path, 0, std::string("detector.") + key + ": expected an integer from 1 to 16384");
  s.detector.cols = det["cols"].get<int>();
  s.detector.rows = det["rows"].get<int>();
  if (std::int64_t{s.detector.cols} * s.detector.rows > geometry::kMaxImagePixels)
    fail(json_path, 0, "detector: " + std::to_string(s.detector.cols) + " x " + std::to_string(s.detector.rows) +
                           " pixels; at most " + std::to_string(geometry::kMaxImagePixels) + " in all");
  s.detector.row_spacing_mm = positive("row_spacing_mm");
  s.detector.col_spacing_mm = positive("col_spacing_mm");
  const auto& streams = field("streams");
  if (!streams.is_object() || !streams.contains("frames") || !streams.contains("carm") || !streams["frames"].is_string() ||
      !streams["carm"].is_string() || !inside_path(streams["frames"].get<std::string>()) ||
      !inside_path(streams["carm"].get<std::string>()))
    fail(json_path, 0, "streams: expected {\"frames\": \"frames/index.csv\", \"carm\": \"carm.csv\"} (relative paths inside the session)");
  s.frames_index = streams["frames"].get<std::string>();

  // Frames.
  const fs::path index = directory / streams["frames"].get<std::string>();
  for_each_row(index, kFramesHeader, 4, [&](std::size_t line, const std::vector<std::string>& f) {
    FrameRecord r;
    r.frame = number<std::int64_t>(index, line, "frame", f[0]);
    r.timestamp_ns = number<std::int64_t>(index, line, "timestamp_ns", f[1]);
    if (!plain_name(f[2])) fail(index, line, "source: '" + f[2] + "' (letters, digits, '_', '-', '.')");
    r.source = f[2];
    const fs::path file(f[3]);
    if (f[3].empty() || file.is_absolute() || f[3].find("..") != std::string::npos)
      fail(index, line, "file: '" + f[3] + "' must be a relative path inside the frames folder");
    r.file = file;
    if (!s.frames.empty()) {
      if (r.frame <= s.frames.back().frame) fail(index, line, "frame: " + f[0] + " does not increase");
      if (r.timestamp_ns < s.frames.back().timestamp_ns) fail(index, line, "timestamp_ns: goes back in time");
    }
    if (!fs::is_regular_file(index.parent_path() / file)) fail(index, line, "file: " + f[3] + " is missing");
    s.frames.push_back(std::move(r));
  });

  // C-arm geometry stream.
  const fs::path carm = directory / streams["carm"].get<std::string>();
  for_each_row(carm, kCArmHeader, 10, [&](std::size_t line, const std::vector<std::string>& f) {
    CArmSample c;
    c.timestamp_ns = number<std::int64_t>(carm, line, "timestamp_ns", f[0]);
    c.primary_deg = number<double>(carm, line, "primary_deg", f[1]);
    c.secondary_deg = number<double>(carm, line, "secondary_deg", f[2]);
    c.sid_mm = number<double>(carm, line, "sid_mm", f[3]);
    c.sod_mm = number<double>(carm, line, "sod_mm", f[4]);
    for (int k = 0; k < 3; ++k)
      c.table_mm(k) = number<double>(carm, line, k == 0 ? "table_x_mm" : k == 1 ? "table_y_mm" : "table_z_mm", f[5 + static_cast<std::size_t>(k)]);
    c.fluoro_on = flag(carm, line, "fluoro_on", f[8]);
    c.moving = flag(carm, line, "moving", f[9]);
    if (std::abs(c.primary_deg) > 180.0) fail(carm, line, "primary_deg: " + f[1] + " is outside -180 to 180");
    if (std::abs(c.secondary_deg) > 90.0) fail(carm, line, "secondary_deg: " + f[2] + " is outside -90 to 90");
    if (!(c.sod_mm > 0.0 && c.sod_mm < c.sid_mm && c.sid_mm <= 5000.0))
      fail(carm, line, "sid_mm, sod_mm: need 0 < SOD < SID <= 5000");
    if (!s.carm.empty() && c.timestamp_ns < s.carm.back().timestamp_ns) fail(carm, line, "timestamp_ns: goes back in time");
    s.carm.push_back(c);
  });

  // Ground truth (optional).
  if (j.contains("ground_truth")) {
    const auto& g = j["ground_truth"];
    SessionTruth truth;
    const auto truth_file = [&](const char* key) {
      if (!g.is_object() || !g.contains(key) || !g[key].is_string() || !inside_path(g[key].get<std::string>()))
        fail(json_path, 0, std::string("ground_truth.") + key + ": expected a relative file name inside the session");
      const fs::path p = g[key].get<std::string>();
      if (!fs::is_regular_file(directory / p)) fail(json_path, 0, std::string("ground_truth.") + key + ": " + p.string() + " is missing");
      return p;
    };
    truth.scene = truth_file("scene");
    truth.device = truth_file("device");
    truth.ostia_2d = truth_file("ostia_2d");
    const fs::path ostia = directory / truth.ostia_2d;
    for_each_row(ostia, kOstiaHeader, 4, [&](std::size_t line, const std::vector<std::string>& f) {
      OstiumTruth o;
      o.frame = number<std::int64_t>(ostia, line, "frame", f[0]);
      const bool known = std::binary_search(s.frames.begin(), s.frames.end(), o.frame,
                                            [](const auto& a, const auto& b) {
                                              if constexpr (std::is_same_v<std::decay_t<decltype(a)>, FrameRecord>) return a.frame < b;
                                              else return a < b.frame;
                                            });
      if (!known) fail(ostia, line, "frame: " + f[0] + " is not in the frames index");
      if (!plain_name(f[1])) fail(ostia, line, "label: '" + f[1] + "' (letters, digits, '_', '-', '.')");
      o.label = f[1];
      o.pixel = {number<double>(ostia, line, "u_px", f[2]), number<double>(ostia, line, "v_px", f[3])};
      truth.ostia.push_back(std::move(o));
    });
    s.truth = std::move(truth);
  }
  return s;
}

cv::Mat read_session_frame(const Session& session, std::size_t index) {
  if (index >= session.frames.size()) throw std::out_of_range("read_session_frame: no frame " + std::to_string(index));
  const fs::path file = (session.directory / session.frames_index).parent_path() / session.frames[index].file;
  const cv::Mat image = geometry::read_image_file(file);
  if (image.type() != CV_16UC1) fail(file, 0, "expected a 16-bit single-channel PNG");
  if (image.cols != session.detector.cols || image.rows != session.detector.rows)
    fail(file, 0, std::to_string(image.cols) + " x " + std::to_string(image.rows) + " pixels, but the detector is " +
                      std::to_string(session.detector.cols) + " x " + std::to_string(session.detector.rows));
  return image;
}

void write_session_frame(const std::filesystem::path& directory, const FrameRecord& f, const cv::Mat& image) {
  if (image.type() != CV_16UC1) throw std::invalid_argument("write_session: frames must be CV_16UC1");
  if (!plain_name(f.source) || f.file.empty() || f.file.is_absolute())
    throw std::invalid_argument("write_session: frame " + std::to_string(f.frame) + " has a bad source or file name");
  const fs::path out = directory / "frames" / f.file;
  fs::create_directories(out.parent_path());
  if (!cv::imwrite(out.string(), image, {cv::IMWRITE_PNG_COMPRESSION, 1})) throw std::runtime_error(out.string() + ": cannot write");
}

void write_session_files(const std::filesystem::path& directory, const Session& session) {
  const DetectorSpec& d = session.detector;
  if (d.cols <= 0 || d.rows <= 0 || d.cols > 16384 || d.rows > 16384 || !(d.row_spacing_mm > 0.0) || !(d.col_spacing_mm > 0.0))
    throw std::invalid_argument("write_session: the detector needs a positive size and spacing");
  fs::create_directories(directory / "frames");
  std::string index = std::string(kFramesHeader) + "\n";
  for (std::size_t i = 0; i < session.frames.size(); ++i) {
    const auto& f = session.frames[i];
    if (i > 0 && (f.frame <= session.frames[i - 1].frame || f.timestamp_ns < session.frames[i - 1].timestamp_ns))
      throw std::invalid_argument("write_session: frames must have increasing numbers and non-decreasing times");
    if (!fs::is_regular_file(directory / "frames" / f.file))
      throw std::invalid_argument("write_session: frame " + std::to_string(f.frame) + " has no image written");
    index += std::to_string(f.frame) + "," + std::to_string(f.timestamp_ns) + "," + f.source + "," + f.file.generic_string() + "\n";
  }
  write_text(directory / "frames" / "index.csv", index);
  std::string carm = std::string(kCArmHeader) + "\n";
  for (const auto& c : session.carm)
    carm += std::to_string(c.timestamp_ns) + "," + exact(c.primary_deg) + "," + exact(c.secondary_deg) + "," + exact(c.sid_mm) +
            "," + exact(c.sod_mm) + "," + exact(c.table_mm.x()) + "," + exact(c.table_mm.y()) + "," + exact(c.table_mm.z()) +
            "," + (c.fluoro_on ? "1" : "0") + "," + (c.moving ? "1" : "0") + "\n";
  write_text(directory / "carm.csv", carm);
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r)
    rows.push_back({session.ct_to_carm(r, 0), session.ct_to_carm(r, 1), session.ct_to_carm(r, 2), session.ct_to_carm(r, 3)});
  write_text(directory / "registration.json", nlohmann::json{{"matrix", rows}}.dump(2) + "\n");
  nlohmann::ordered_json j{{"format", kFormat},
                           {"version", kVersion},
                           {"scene", session.scene.generic_string()},
                           {"registration", "registration.json"},
                           {"device_thickness_mm", session.device_thickness_mm},
                           {"detector",
                            {{"cols", d.cols}, {"rows", d.rows}, {"row_spacing_mm", d.row_spacing_mm}, {"col_spacing_mm", d.col_spacing_mm}}},
                           {"streams", {{"frames", "frames/index.csv"}, {"carm", "carm.csv"}}}};
  if (session.truth) {
    const SessionTruth& t = *session.truth;
    for (const fs::path& p : {t.scene, t.device, t.ostia_2d})
      if (!inside_path(p.generic_string())) throw std::invalid_argument("write_session: ground-truth paths must be relative, inside the session");
    for (const fs::path& p : {t.scene, t.device})
      if (!fs::is_regular_file(directory / p)) throw std::invalid_argument("write_session: ground truth " + p.generic_string() + " is missing");
    std::string ostia = std::string(kOstiaHeader) + "\n";
    for (const auto& o : t.ostia) {
      if (!plain_name(o.label)) throw std::invalid_argument("write_session: bad ostium label '" + o.label + "'");
      if (std::none_of(session.frames.begin(), session.frames.end(), [&](const FrameRecord& f) { return f.frame == o.frame; }))
        throw std::invalid_argument("write_session: ostium for frame " + std::to_string(o.frame) + ", which is not in the session");
      ostia += std::to_string(o.frame) + "," + o.label + "," + exact(o.pixel.x()) + "," + exact(o.pixel.y()) + "\n";
    }
    fs::create_directories((directory / t.ostia_2d).parent_path());
    write_text(directory / t.ostia_2d, ostia);
    j["ground_truth"] = {{"scene", t.scene.generic_string()}, {"device", t.device.generic_string()}, {"ostia_2d", t.ostia_2d.generic_string()}};
  }
  // session.json last: a reader never finds it naming files not yet written.
  write_text(directory / "session.json", j.dump(2) + "\n");
}

void write_session(const std::filesystem::path& directory, const Session& session, const std::vector<cv::Mat>& images) {
  if (images.size() != session.frames.size())
    throw std::invalid_argument("write_session: one image per frame record is required");
  for (const auto& image : images)
    if (image.cols != session.detector.cols || image.rows != session.detector.rows)
      throw std::invalid_argument("write_session: every image must have the detector's size");
  for (std::size_t i = 0; i < session.frames.size(); ++i) write_session_frame(directory, session.frames[i], images[i]);
  write_session_files(directory, session);
}

geometry::CArmView view_of(const DetectorSpec& detector, double primary_deg, double secondary_deg, double sid_mm,
                           double sod_mm) {
  geometry::CArmView v;
  v.primary_angle_deg = primary_deg;
  v.secondary_angle_deg = secondary_deg;
  v.source_to_detector_mm = sid_mm;
  v.source_to_isocenter_mm = sod_mm;
  v.detector_cols = detector.cols;
  v.detector_rows = detector.rows;
  v.row_spacing_mm = detector.row_spacing_mm;
  v.col_spacing_mm = detector.col_spacing_mm;
  return v;
}

geometry::CArmView view_of(const Session& session, const CArmSample& c) {
  return view_of(session.detector, c.primary_deg, c.secondary_deg, c.sid_mm, c.sod_mm);
}

Eigen::Matrix4d patient_to_carm(const Eigen::Matrix4d& ct_to_carm, const Eigen::Vector3d& table_mm) {
  Eigen::Matrix4d T = ct_to_carm;
  T.topRightCorner<3, 1>() += table_mm;
  return T;
}

Eigen::Matrix4d patient_to_carm(const Session& session, const CArmSample& c) {
  return patient_to_carm(session.ct_to_carm, c.table_mm);
}

const CArmSample* carm_at(const Session& session, std::int64_t timestamp_ns) {
  if (session.carm.empty()) return nullptr;
  const auto after = std::upper_bound(session.carm.begin(), session.carm.end(), timestamp_ns,
                                      [](std::int64_t t, const CArmSample& c) { return t < c.timestamp_ns; });
  return after == session.carm.begin() ? &session.carm.front() : &*(after - 1);
}

void export_plus_sequence(const Session& session, const std::filesystem::path& mha,
                          const std::function<void(std::size_t, std::size_t)>& progress) {
  if (session.frames.empty()) throw std::invalid_argument("export_plus_sequence: the session has no frames");
  // The frames are streamed one at a time (an hour's recording does not fit in memory);
  // read_session_frame refuses any frame that is not the detector's size.
  const int W = session.detector.cols, H = session.detector.rows;
  std::ostringstream h;
  h << "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\nCompressedData = False\n"
    << "Kinds = domain domain list\nTransformMatrix = 1 0 0 0 1 0 0 0 1\nDimSize = " << W << " " << H << " "
    << session.frames.size() << "\nOffset = 0 0 0\nCenterOfRotation = 0 0 0\nAnatomicalOrientation = RAI\n"
    << "ElementSpacing = 1 1 1\nElementType = MET_USHORT\nUltrasoundImageOrientation = MFA\n";
  const std::int64_t t0 = session.frames.front().timestamp_ns;
  char name[32];
  for (std::size_t i = 0; i < session.frames.size(); ++i) {
    const auto& f = session.frames[i];
    std::snprintf(name, sizeof name, "Seq_Frame%04zu_", i);
    h << name << "FrameNumber = " << f.frame << "\n";
    h << name << "Timestamp = " << exact(static_cast<double>(f.timestamp_ns - t0) * 1e-9) << "\n";
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

  // Written beside the target and renamed over it: a failure leaves no partial sequence.
  std::filesystem::path partial = mha;
  partial += ".partial";
  try {
    std::ofstream out(partial, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error(partial.string() + ": cannot create");
    out << h.str();
    std::vector<char> row(static_cast<std::size_t>(W) * 2);
    for (std::size_t i = 0; i < session.frames.size(); ++i) {
      const cv::Mat image = read_session_frame(session, i);
      for (int r = 0; r < H; ++r) {
        const auto* px = image.ptr<std::uint16_t>(r);
        for (int c = 0; c < W; ++c) {  // little endian, whatever the host
          row[2 * static_cast<std::size_t>(c)] = static_cast<char>(px[c] & 0xff);
          row[2 * static_cast<std::size_t>(c) + 1] = static_cast<char>(px[c] >> 8);
        }
        out.write(row.data(), static_cast<std::streamsize>(row.size()));
      }
      if (progress) progress(i + 1, session.frames.size());
    }
    out.close();
    if (!out) throw std::runtime_error(partial.string() + ": cannot write (disk full?)");
    std::filesystem::rename(partial, mha);
  } catch (...) {
    std::error_code ignored;
    std::filesystem::remove(partial, ignored);
    throw;
  }
}

}  // namespace evar::sim
