#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <cmath>
#include <map>
#include <regex>
#include <unistd.h>

#include "evar/base/input_error.hpp"
#include "evar/base/input_file.hpp"
#include "evar/session/session.hpp"
#include "support/error_message.hpp"
#include "support/temp_dir.hpp"

using namespace evar;
namespace fs = std::filesystem;

namespace {

using evar::test::TempDir;

session::Session small_session(std::vector<cv::Mat>& images) {
  session::Session s;
  s.scene = "patient/scene.json";
  s.ct_to_carm.block<3, 1>(0, 3) = Eigen::Vector3d(1.25, -2.5, -60.125);
  s.device_thickness_mm = 0.89;
  s.detector = {60, 40, 0.3, 0.3 + 1e-14};
  for (int k = 0; k < 3; ++k) {
    s.frames.push_back({k + 1, 1'000'000'000LL + k * 66'666'667LL, k == 2 ? "dsa" : "fluoro", "f" + std::to_string(k) + ".png"});
    cv::Mat img(40, 60, CV_16UC1);
    cv::randu(img, 0, 65535);
    images.push_back(img);
  }
  for (int k = 0; k < 4; ++k) {
    session::CArmSample c;
    c.timestamp_ns = 990'000'000LL + k * 33'333'333LL;
    c.primary_deg = 30.0 + 0.1 * k + 1e-13;  // not representable in a few digits
    c.secondary_deg = -7.0 / 3.0;
    c.sid_mm = 1200.0;
    c.sod_mm = 785.5;
    c.table_mm = {0.1, -0.2, 1.0 / 3.0};
    c.fluoro_on = k != 0;
    c.moving = k == 3;
    s.carm.push_back(c);
  }
  return s;
}

void replace_in(const fs::path& file, const std::string& from, const std::string& to) {
  std::ifstream in(file);
  std::string text((std::istreambuf_iterator<char>(in)), {});
  const auto at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
  std::ofstream(file) << text;
}

// The session written afresh into `dir` (what a test altered before is gone).
void write_afresh(const fs::path& dir, const session::Session& s, const std::vector<cv::Mat>& images) {
  fs::remove_all(dir);
  session::write_session(dir, s, images);
}

// The small session written to dir/s and exported to dir/run.seq.mha; its frames.
std::vector<cv::Mat> export_small_session(const fs::path& dir) {
  std::vector<cv::Mat> images;
  const auto s = small_session(images);
  session::write_session(dir / "s", s, images);
  session::export_plus_sequence(session::read_session(dir / "s"), dir / "run.seq.mha");
  return images;
}

std::string error_reading(const fs::path& dir) {
  try {
    session::read_session(dir);
  } catch (const base::InputError& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST(Session, RoundTripsBitExactly) {
  TempDir dir;
  std::vector<cv::Mat> images;
  const auto s = small_session(images);
  session::write_session(dir.path, s, images);
  const auto r = session::read_session(dir.path);
  EXPECT_EQ(r.scene, s.scene);
  EXPECT_EQ(r.ct_to_carm, s.ct_to_carm);
  EXPECT_EQ(r.device_thickness_mm, s.device_thickness_mm);
  ASSERT_EQ(r.frames.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(r.frames[i].frame, s.frames[i].frame);
    EXPECT_EQ(r.frames[i].timestamp_ns, s.frames[i].timestamp_ns);
    EXPECT_EQ(r.frames[i].source, s.frames[i].source);
    EXPECT_EQ(cv::norm(session::read_session_frame(r, i), images[i], cv::NORM_INF), 0.0);
  }
  ASSERT_EQ(r.carm.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(r.carm[i].timestamp_ns, s.carm[i].timestamp_ns);
    EXPECT_EQ(r.carm[i].primary_deg, s.carm[i].primary_deg);  // bit-exact
    EXPECT_EQ(r.carm[i].secondary_deg, s.carm[i].secondary_deg);
    EXPECT_EQ(r.carm[i].table_mm, s.carm[i].table_mm);
    EXPECT_EQ(r.carm[i].fluoro_on, s.carm[i].fluoro_on);
    EXPECT_EQ(r.carm[i].moving, s.carm[i].moving);
  }
  EXPECT_EQ(r.detector.cols, 60);
  EXPECT_EQ(r.detector.rows, 40);
  EXPECT_EQ(r.detector.col_spacing_mm, s.detector.col_spacing_mm);  // bit-exact
  EXPECT_FALSE(r.truth.has_value());
}

// The files a session's ground truth names (their contents are not read here).
static void write_truth_stand_ins(const fs::path& session) {
  fs::create_directories(session / "patient" / "truth");
  std::ofstream(session / "patient" / "truth" / "scene.json") << "{}";
  std::ofstream(session / "patient" / "device.mrk.json") << "{}";
}

// The true registration of a session whose given one is off (the paper's difficulty):
// written as truth/registration.json, read back exactly, absent when not set, and a
// missing file is named.
TEST(Session, ATrueRegistrationRoundTripsAndAMissingOneIsNamed) {
  TempDir dir;
  std::vector<cv::Mat> images;
  auto s = small_session(images);
  write_truth_stand_ins(dir.path);
  s.truth = session::SessionTruth{"patient/truth/scene.json", "patient/device.mrk.json", "truth/ostia_2d.csv", {}, std::nullopt};
  session::write_session(dir.path, s, images);
  EXPECT_FALSE(session::read_session(dir.path).truth->ct_to_carm.has_value());
  EXPECT_FALSE(fs::exists(dir.path / "truth" / "registration.json"));
  Eigen::Matrix4d truth = s.ct_to_carm;
  truth.topRightCorner<3, 1>() += Eigen::Vector3d(0.25, -1.0 / 3.0, 2.0);
  s.truth->ct_to_carm = truth;
  session::write_session(dir.path, s, images);
  const auto r = session::read_session(dir.path);
  ASSERT_TRUE(r.truth->ct_to_carm.has_value());
  EXPECT_EQ(*r.truth->ct_to_carm, truth);
  EXPECT_EQ(r.ct_to_carm, s.ct_to_carm);
  fs::remove(dir.path / "truth" / "registration.json");
  EXPECT_NE(error_reading(dir.path).find("ground_truth.registration: truth/registration.json is missing"), std::string::npos)
      << error_reading(dir.path);
}

TEST(Session, GroundTruthRoundTripsAndItsErrorsAreNamed) {
  TempDir dir;
  std::vector<cv::Mat> images;
  auto s = small_session(images);
  write_truth_stand_ins(dir.path);
  s.truth = session::SessionTruth{"patient/truth/scene.json", "patient/device.mrk.json", "truth/ostia_2d.csv",
                              {{1, "renal_left", {10.5, 20.0 / 3.0}}, {3, "internal_iliac_right", {-4.0, 1e-9}}}, std::nullopt};
  session::write_session(dir.path, s, images);
  const auto r = session::read_session(dir.path);
  ASSERT_TRUE(r.truth.has_value());
  ASSERT_EQ(r.truth->ostia.size(), 2u);
  EXPECT_EQ(r.truth->ostia[0].pixel, s.truth->ostia[0].pixel);
  EXPECT_EQ(r.truth->ostia[1].label, "internal_iliac_right");
  EXPECT_EQ(r.truth->scene, s.truth->scene);
  replace_in(dir.path / "truth" / "ostia_2d.csv", "3,internal", "7,internal");
  EXPECT_NE(error_reading(dir.path).find("ostia_2d.csv:3: frame: 7 is not in the frames index"), std::string::npos)
      << error_reading(dir.path);
  fs::remove(dir.path / "patient" / "device.mrk.json");
  EXPECT_NE(error_reading(dir.path).find("ground_truth.device: patient/device.mrk.json is missing"), std::string::npos)
      << error_reading(dir.path);
}

TEST(Session, AFrameOfAnotherSizeThanTheDetectorIsRefused) {
  TempDir dir;
  std::vector<cv::Mat> images;
  auto s = small_session(images);
  session::write_session(dir.path, s, images);
  auto wrong = images;
  wrong[1] = cv::Mat(41, 60, CV_16UC1, cv::Scalar(5));
  EXPECT_THROW(session::write_session(dir.path, s, wrong), std::invalid_argument);  // the writer refuses it too
  cv::imwrite((dir.path / "frames" / "f1.png").string(), wrong[1]);                // a file changed behind its back
  const auto r = session::read_session(dir.path);
  try {
    session::read_session_frame(r, 1);
    FAIL() << "no error";
  } catch (const base::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("f1.png: 60 x 41 pixels, but the detector is 60 x 40"), std::string::npos) << e.what();
  }
}

TEST(Session, CorruptFilesAreNamedWithTheirLine) {
  TempDir dir;
  std::vector<cv::Mat> images;
  const auto s = small_session(images);
  const auto fresh = [&] { write_afresh(dir.path, s, images); };
  fresh();
  replace_in(dir.path / "carm.csv", "785.5", "78x5.5");
  EXPECT_NE(error_reading(dir.path).find("carm.csv:2: sod_mm: '78x5.5' is not a number"), std::string::npos)
      << error_reading(dir.path);
  fresh();
  replace_in(dir.path / "carm.csv", ",1,1\n", ",1,2\n");
  EXPECT_NE(error_reading(dir.path).find("carm.csv:5: moving"), std::string::npos) << error_reading(dir.path);
  fresh();
  replace_in(dir.path / "frames" / "index.csv", "2,", "1,");
  EXPECT_NE(error_reading(dir.path).find("index.csv:3: frame: 1 does not increase"), std::string::npos)
      << error_reading(dir.path);
  fresh();
  fs::remove(dir.path / "frames" / "f1.png");
  EXPECT_NE(error_reading(dir.path).find("index.csv:3: file: f1.png is missing"), std::string::npos) << error_reading(dir.path);
  fresh();
  replace_in(dir.path / "frames" / "index.csv", ",f0.png", ",../../etc/passwd");
  EXPECT_NE(error_reading(dir.path).find("must be a relative path inside"), std::string::npos) << error_reading(dir.path);
  fresh();
  replace_in(dir.path / "session.json", "\"version\": 1", "\"version\": 7");
  EXPECT_NE(error_reading(dir.path).find("session.json: version: unsupported 7"), std::string::npos) << error_reading(dir.path);
  fresh();
  replace_in(dir.path / "carm.csv", "timestamp_ns,primary_deg", "timestamp,primary_deg");
  EXPECT_NE(error_reading(dir.path).find("carm.csv:1: header"), std::string::npos) << error_reading(dir.path);
  fresh();  // each side allowed, 2^28 pixels in all are not
  replace_in(dir.path / "session.json", "\"cols\": 60", "\"cols\": 16384");
  replace_in(dir.path / "session.json", "\"rows\": 40", "\"rows\": 16384");
  EXPECT_NE(error_reading(dir.path).find("session.json: detector: 16384 x 16384 pixels; at most 67108864 in all"),
            std::string::npos)
      << error_reading(dir.path);
}

// A file cut at any byte gives an error naming it (and, in a table, the line) or a valid,
// shorter session: a cut at a line end (tables) or in trailing whitespace (JSON). A table
// cut inside its last number once read as a different number (ostia_2d.csv's last u_px
// "40.6" as 40.).
TEST(Session, TruncatedFilesAreClearErrorsAtEveryLength) {
  TempDir dir;
  std::vector<cv::Mat> images;
  auto s = small_session(images);
  write_truth_stand_ins(dir.path);
  s.truth = session::SessionTruth{"patient/truth/scene.json", "patient/device.mrk.json", "truth/ostia_2d.csv",
                              {{1, "renal_left", {10.5, 20.0 / 3.0}}, {3, "internal_iliac_right", {-4.0, 40.625}}}, std::nullopt};
  session::write_session(dir.path, s, images);
  for (const char* name : {"session.json", "carm.csv", "frames/index.csv", "truth/ostia_2d.csv"}) {
    const bool table = std::string(name) != "session.json";
    std::ifstream in(dir.path / name, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), {});
    const std::string file = fs::path(name).filename().string();
    std::vector<std::size_t> lengths;
    for (std::size_t n = 0; n < bytes.size(); n += 7) lengths.push_back(n);
    lengths.push_back(bytes.size() - 2);  // inside the last number (tables) or the closing brace
    for (const std::size_t n : lengths) {
      std::ofstream(dir.path / name, std::ios::binary | std::ios::trunc) << bytes.substr(0, n);
      const std::string error = error_reading(dir.path);
      const bool at_line_end = n > 0 && bytes[n - 1] == '\n';
      if (error == "no error") {
        EXPECT_TRUE(table ? at_line_end : bytes.find_first_not_of(" \n", n) == std::string::npos)
            << name << " cut to " << n << " bytes read as a valid session";
      } else if (table && !at_line_end) {  // the cut row itself is named
        EXPECT_TRUE(std::regex_search(error, std::regex(file + ":[0-9]+: "))) << name << " cut to " << n << ": " << error;
      } else if (table) {  // rows lost whole: a file that refers to them may be the one named
        EXPECT_TRUE(std::regex_search(error, std::regex("\\.csv:[0-9]+: "))) << name << " cut to " << n << ": " << error;
      } else {
        EXPECT_NE(error.find(file + ": "), std::string::npos) << name << " cut to " << n << ": " << error;
      }
    }
    std::ofstream(dir.path / name, std::ios::binary | std::ios::trunc) << bytes;
  }
  // The message for a cut inside the last row says so.
  std::ifstream in(dir.path / "truth" / "ostia_2d.csv", std::ios::binary);
  const std::string ostia((std::istreambuf_iterator<char>(in)), {});
  std::ofstream(dir.path / "truth" / "ostia_2d.csv", std::ios::binary | std::ios::trunc) << ostia.substr(0, ostia.size() - 3);
  EXPECT_NE(error_reading(dir.path).find("ostia_2d.csv:3: cut short"), std::string::npos) << error_reading(dir.path);
  std::ofstream(dir.path / "truth" / "ostia_2d.csv", std::ios::binary | std::ios::trunc) << ostia;
  std::ofstream(dir.path / "frames" / "f0.png", std::ios::binary | std::ios::trunc) << "\x89PNG garbage";
  const auto r = session::read_session(dir.path);
  EXPECT_THROW(session::read_session_frame(r, 0), base::InputError);
}

TEST(Session, ExportsAPlusSequenceMetafileForSlicer) {
  TempDir dir;
  const auto images = export_small_session(dir.path);
  std::ifstream in(dir.path / "run.seq.mha", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  const std::string marker = "ElementDataFile = LOCAL\n";
  const auto header_end = bytes.find(marker);
  ASSERT_NE(header_end, std::string::npos);
  const std::string header = bytes.substr(0, header_end);
  EXPECT_NE(header.find("DimSize = 60 40 3\n"), std::string::npos);
  EXPECT_NE(header.find("ElementType = MET_USHORT\n"), std::string::npos);
  EXPECT_NE(header.find("Seq_Frame0000_Timestamp = 0.000\n"), std::string::npos) << header;
  EXPECT_NE(header.find("Seq_Frame0001_Timestamp = 0.067\n"), std::string::npos) << header;
  EXPECT_NE(header.find("Seq_Frame0002_Source = dsa\n"), std::string::npos);
  // Frame 0 (t = 1.0 s) falls under the sample at 0.99 s; frame 2 (1.133 s) under 1.089 s.
  EXPECT_NE(header.find("Seq_Frame0000_CArmMoving = 0\n"), std::string::npos);
  EXPECT_NE(header.find("Seq_Frame0000_PrimaryAngleDeg = 30.0000000000001\n"), std::string::npos) << header;
  const std::string payload = bytes.substr(header_end + marker.size());
  ASSERT_EQ(payload.size(), 60u * 40u * 3u * 2u);
  for (int k = 0; k < 3; ++k)  // little endian, frame after frame, row after row
    for (const auto& [r0, c0] : {std::pair{0, 0}, std::pair{39, 59}, std::pair{17, 23}}) {
      const std::size_t at = 2 * (static_cast<std::size_t>(k) * 2400 + static_cast<std::size_t>(r0) * 60 + static_cast<std::size_t>(c0));
      const unsigned v = static_cast<unsigned char>(payload[at]) | (static_cast<unsigned char>(payload[at + 1]) << 8);
      EXPECT_EQ(v, images[static_cast<std::size_t>(k)].at<std::uint16_t>(r0, c0));
    }
}

TEST(Session, TheCArmSampleInForceIsTheLastOneBefore) {
  std::vector<cv::Mat> images;
  const auto s = small_session(images);
  EXPECT_EQ(session::carm_at(s, 0), &s.carm[0]);                   // before all: the first
  EXPECT_EQ(session::carm_at(s, 1'023'333'333LL), &s.carm[1]);     // exactly at a sample
  EXPECT_EQ(session::carm_at(s, 1'050'000'000LL), &s.carm[1]);
  EXPECT_EQ(session::carm_at(s, 9'000'000'000LL), &s.carm[3]);     // after all: the last
  EXPECT_EQ(session::carm_at(session::Session{}, 5), nullptr);
}

TEST(Session, AnOversizedTableOrFrameIsRefusedByNameBeforeItIsRead) {
  TempDir dir;
  std::vector<cv::Mat> images;
  const auto s = small_session(images);
  session::write_session(dir.path, s, images);
  fs::resize_file(dir.path / "carm.csv", base::kTableLimit.bytes + 1);  // sparse: no disk used
  EXPECT_NE(error_reading(dir.path).find("carm.csv: is 268435457 bytes, more than the 256 MiB accepted for a CSV table"),
            std::string::npos)
      << error_reading(dir.path);
  session::write_session(dir.path, s, images);
  const auto r = session::read_session(dir.path);
  fs::resize_file(dir.path / "frames" / "f0.png", base::kImageLimit.bytes + 1);
  try {
    session::read_session_frame(r, 0);
    FAIL() << "no error";
  } catch (const base::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("f0.png: is 268435457 bytes, more than the 256 MiB accepted for an image file"),
              std::string::npos)
        << e.what();
  }
}

// The writers took what read_session refuses (SID beyond 5000 mm, angles out of range,
// numbers that are not finite, C-arm time going back, file names that break a CSV row or
// leave frames/, more pixels than the detector limit, non-finite ostia), so a session could
// be written that no reader takes. They share the reader's rules now, and write nothing.
TEST(Session, WritersRefuseWhatTheReaderRefuses) {
  TempDir dir;
  std::vector<cv::Mat> images;
  const auto good = small_session(images);
  const auto refused = [&](const std::function<void(session::Session&)>& spoil, const std::string& expected) {
    fs::remove_all(dir.path);
    for (std::size_t i = 0; i < good.frames.size(); ++i) session::write_session_frame(dir.path, good.frames[i], images[i]);
    auto s = good;
    spoil(s);
    std::string what = "no error";
    try {
      session::write_session_files(dir.path, s);
    } catch (const std::invalid_argument& e) {
      what = e.what();
    }
    EXPECT_NE(what.find(expected), std::string::npos) << what;
    EXPECT_FALSE(fs::exists(dir.path / "session.json")) << expected;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  refused([](session::Session& s) { s.carm[1].sid_mm = 5000.5; }, "C-arm sample 1: sid_mm, sod_mm: need 0 < SOD < SID <= 5000");
  refused([](session::Session& s) { s.carm[1].sod_mm = s.carm[1].sid_mm; }, "sid_mm, sod_mm");
  refused([](session::Session& s) { s.carm[2].primary_deg = 180.5; }, "primary_deg: 180.5 is outside -180 to 180");
  refused([](session::Session& s) { s.carm[2].secondary_deg = -91; }, "secondary_deg: -91 is outside -90 to 90");
  refused([&](session::Session& s) { s.carm[0].table_mm[1] = nan; }, "table_y_mm: nan is not finite");
  refused([](session::Session& s) { s.carm[3].timestamp_ns = s.carm[2].timestamp_ns - 1; }, "C-arm sample 3: timestamp_ns: goes back in time");
  refused([](session::Session& s) { s.frames[1].file = "f,1.png"; }, "frame 2: file: 'f,1.png' must be a relative path");
  refused([](session::Session& s) { s.frames[1].file = "f\n1.png"; }, "holds a comma or a control character");
  refused([](session::Session& s) { s.frames[1].file = "../f1.png"; }, "has a '..' component");
  refused([](session::Session& s) { s.frames[1].source = "fluoro,dsa"; }, "frame 2: source: 'fluoro,dsa'");
  refused([](session::Session& s) { s.frames[2].timestamp_ns = -5; }, "frame 3: timestamp_ns: -5 is outside 0 to 2^62 ns");
  refused([](session::Session& s) { s.detector.cols = s.detector.rows = 9000; }, "detector: 9000 x 9000 pixels; at most 67108864");
  refused([](session::Session& s) { s.scene = "/etc/scene.json"; }, "scene: '/etc/scene.json' must be a relative file name");
  refused([](session::Session& s) { s.device_thickness_mm = 16; }, "device_thickness_mm: must be 0 to 15");
  refused([](session::Session& s) { s.ct_to_carm(0, 0) = -1; }, "registration: ");
  refused([&](session::Session& s) { s.truth = session::SessionTruth{"t.json", "d.json", "o.csv", {{1, "renal_left", {nan, 2.0}}}, std::nullopt}; },
          "ground truth 't.json' is missing");
  refused(
      [&](session::Session& s) {
        std::ofstream(dir.path / "t.json") << "{}";
        std::ofstream(dir.path / "d.json") << "{}";
        s.truth = session::SessionTruth{"t.json", "d.json", "o.csv", {{1, "renal_left", {nan, 2.0}}}, std::nullopt};
      },
      "ostium of frame 1: u_px: nan is not finite");
  // And what the writers take, the reader takes.
  fs::remove_all(dir.path);
  session::write_session(dir.path, good, images);
  EXPECT_EQ(session::read_session(dir.path).carm.size(), good.carm.size());
}

// Timestamps are held to 0 <= t < 2^62 ns, so their differences (replay loops, the export)
// cannot overflow 64 bits; any int64 was read before.
TEST(Session, TimestampsOutsideTheFormatsRangeAreRefusedByFileAndLine) {
  TempDir dir;
  std::vector<cv::Mat> images;
  const auto s = small_session(images);
  const auto fresh = [&] { write_afresh(dir.path, s, images); };
  fresh();
  replace_in(dir.path / "frames" / "index.csv", "1,1000000000,", "1,-1,");
  EXPECT_NE(error_reading(dir.path).find("index.csv:2: timestamp_ns: -1 is outside 0 to 2^62 ns"), std::string::npos)
      << error_reading(dir.path);
  fresh();
  replace_in(dir.path / "carm.csv", "1089999999,", "9223372036854775807,");
  EXPECT_NE(error_reading(dir.path).find("carm.csv:5: timestamp_ns: 9223372036854775807 is outside"), std::string::npos)
      << error_reading(dir.path);
  fresh();
  replace_in(dir.path / "carm.csv", "1089999999,", "4611686018427387904,");  // 2^62
  EXPECT_NE(error_reading(dir.path).find("carm.csv:5: timestamp_ns"), std::string::npos) << error_reading(dir.path);
}

// A bad field is quoted up to 40 characters (a 200 MB field made a 200 MB log line), and a
// line longer than any real row is refused before it is split.
TEST(Session, ALongFieldIsQuotedShortAndAHugeLineIsRefused) {
  TempDir dir;
  std::vector<cv::Mat> images;
  const auto s = small_session(images);
  session::write_session(dir.path, s, images);
  replace_in(dir.path / "carm.csv", ",785.5,", "," + std::string(3000, 'x') + ",");
  std::string error = error_reading(dir.path);
  EXPECT_NE(error.find("carm.csv:2: sod_mm: '" + std::string(40, 'x') + "...' is not a number"), std::string::npos) << error;
  EXPECT_LT(error.size(), 300u);
  session::write_session(dir.path, s, images);
  replace_in(dir.path / "frames" / "index.csv", ",f1.png", "," + std::string(1'000'000, 'a') + ".png");
  error = error_reading(dir.path);
  EXPECT_NE(error.find("index.csv:3: a line of 1000024 bytes; rows are at most 4096"), std::string::npos) << error;
  EXPECT_LT(error.size(), 300u);
}

TEST(Session, AFrameThatIsNotAPngIsRefusedWhateverItsName) {
  TempDir dir;
  std::vector<cv::Mat> images;
  const auto s = small_session(images);
  session::write_session(dir.path, s, images);
  cv::imwrite((dir.path / "f1.tiff").string(), images[1]);  // 16-bit TIFF: OpenCV would decode it
  fs::rename(dir.path / "f1.tiff", dir.path / "frames" / "f1.png");
  const auto r = session::read_session(dir.path);
  const std::string error = evar::test::error_message([&] { session::read_session_frame(r, 1); });
  EXPECT_NE(error.find("f1.png: is a TIFF file; only PNG is accepted here"), std::string::npos) << error;
  EXPECT_EQ(cv::norm(session::read_session_frame(r, 0), images[0], cv::NORM_INF), 0.0);
}

// A symbolic link inside the session passed the "inside the session" check wherever it
// led (a frame linked to /etc/passwd); and a name with two dots, a..b.png, was refused.
TEST(Session, SymbolicLinksOutOfTheSessionAreRefusedAndDotsInANameAreNot) {
  TempDir dir;
  std::vector<cv::Mat> images;
  const auto s = small_session(images);
  const fs::path session = dir.path / "s";
  session::write_session(session, s, images);
  cv::imwrite((dir.path / "outside.png").string(), images[1]);
  fs::remove(session / "frames" / "f1.png");
  fs::create_symlink(dir.path / "outside.png", session / "frames" / "f1.png");
  EXPECT_NE(error_reading(session).find("index.csv:3: file: 'f1.png' leads out of the session directory"), std::string::npos)
      << error_reading(session);
  // One replaced by a link after the session was read is refused when it is read.
  fs::remove(session / "frames" / "f1.png");
  cv::imwrite((session / "frames" / "f1.png").string(), images[1]);
  const auto r = session::read_session(session);
  fs::remove(session / "frames" / "f1.png");
  fs::create_symlink(dir.path / "outside.png", session / "frames" / "f1.png");
  EXPECT_NE(evar::test::error_message([&] { session::read_session_frame(r, 1); }).find("leads out of the session directory"),
            std::string::npos);
  // A link that stays inside is fine, and so is a file of session.json's.
  fs::remove(session / "frames" / "f1.png");
  cv::imwrite((session / "f1-elsewhere.png").string(), images[1]);
  fs::create_symlink("../f1-elsewhere.png", session / "frames" / "f1.png");
  EXPECT_EQ(cv::norm(session::read_session_frame(session::read_session(session), 1), images[1], cv::NORM_INF), 0.0);
  fs::rename(session / "registration.json", dir.path / "registration.json");
  fs::create_symlink(dir.path / "registration.json", session / "registration.json");
  EXPECT_NE(error_reading(session).find("session.json: registration: 'registration.json' leads out of the session"),
            std::string::npos)
      << error_reading(session);

  auto dotted = s;
  dotted.frames[1].file = "a..b.png";
  session::write_session(dir.path / "dotted", dotted, images);
  EXPECT_EQ(session::read_session(dir.path / "dotted").frames[1].file, "a..b.png");
}

// PLUS reads a sequence with no UltrasoundImageType as B-mode and needs its orientation MF
// (it has no MFA to MF conversion and refused MFA files); its header fields come in its own
// order, with one channel and the detector's pixel spacing.
TEST(Session, TheExportHeaderIsTheOnePlusWrites) {
  TempDir dir;
  export_small_session(dir.path);
  std::ifstream in(dir.path / "run.seq.mha", std::ios::binary);
  std::vector<std::string> keys;
  std::map<std::string, std::string> value;
  for (std::string line; std::getline(in, line) && line.rfind("Seq_Frame", 0) != 0;) {
    const auto eq = line.find(" = ");
    ASSERT_NE(eq, std::string::npos) << line;
    keys.push_back(line.substr(0, eq));
    value[keys.back()] = line.substr(eq + 3);
  }
  const std::vector<std::string> expected{"ObjectType",       "NDims",          "AnatomicalOrientation", "BinaryData",
                                          "BinaryDataByteOrderMSB", "CenterOfRotation", "CompressedData", "DimSize",
                                          "ElementNumberOfChannels", "ElementSpacing", "ElementType",    "Kinds",
                                          "Offset",           "TransformMatrix", "UltrasoundImageOrientation",
                                          "UltrasoundImageType"};
  EXPECT_EQ(keys, expected);
  EXPECT_EQ(value["UltrasoundImageOrientation"], "MF");
  EXPECT_EQ(value["UltrasoundImageType"], "BRIGHTNESS");
  EXPECT_EQ(value["ElementNumberOfChannels"], "1");
  EXPECT_EQ(value["ElementSpacing"], "0.30000000000001 0.3 1");  // columns (x), rows (y), time
  EXPECT_EQ(value["ElementType"], "MET_USHORT");
}

// Slicer's importer keys frames by their Timestamp printed with 3 decimals: frames at the
// same time, or under 1 ms apart, collapsed into one. Each is at least 1 ms after the last.
TEST(Session, ExportedTimestampsRiseByAtLeastAMillisecond) {
  TempDir dir;
  std::vector<cv::Mat> images;
  auto s = small_session(images);
  s.frames[1].timestamp_ns = s.frames[0].timestamp_ns;            // the same time
  s.frames[2].timestamp_ns = s.frames[0].timestamp_ns + 400'000;  // 0.4 ms later
  session::write_session(dir.path / "s", s, images);
  const auto summary = session::export_plus_sequence(session::read_session(dir.path / "s"), dir.path / "run.seq.mha");
  EXPECT_EQ(summary.frames, 3u);
  EXPECT_EQ(summary.timestamps_nudged, 2u);
  std::ifstream in(dir.path / "run.seq.mha", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  EXPECT_NE(bytes.find("Seq_Frame0000_Timestamp = 0.000\n"), std::string::npos);
  EXPECT_NE(bytes.find("Seq_Frame0001_Timestamp = 0.001\n"), std::string::npos);
  EXPECT_NE(bytes.find("Seq_Frame0002_Timestamp = 0.002\n"), std::string::npos);
}

TEST(Session, TheExportRefusesAnOutputInsideTheSession) {
  TempDir dir;
  std::vector<cv::Mat> images;
  const auto s = small_session(images);
  session::write_session(dir.path / "s", s, images);
  const auto r = session::read_session(dir.path / "s");
  std::ifstream in(dir.path / "s" / "carm.csv", std::ios::binary);
  const std::string carm((std::istreambuf_iterator<char>(in)), {});
  for (const fs::path& out : {dir.path / "s" / "carm.csv", dir.path / "s" / "frames" / "run.seq.mha", dir.path / "s" / "." / "x.seq.mha"}) {
    const std::string error = evar::test::error_message<std::invalid_argument>([&] { session::export_plus_sequence(r, out); });
    EXPECT_NE(error.find("is inside the session directory"), std::string::npos) << out << ": " << error;
  }
  std::ifstream again(dir.path / "s" / "carm.csv", std::ios::binary);
  EXPECT_EQ(std::string((std::istreambuf_iterator<char>(again)), {}), carm);
  EXPECT_FALSE(fs::exists(dir.path / "s" / "frames" / "run.seq.mha"));
  EXPECT_NO_THROW(session::export_plus_sequence(r, dir.path / "run.seq.mha"));
}

// A video-out session (issue 31): its frames are the C-arm monitor's picture, of the video
// mapping's size; the mapping round-trips, the detector image is read back out of each
// frame, a frame of the detector's size is now the wrong one, and a mapping that does not
// fit the detector is refused by the reader and the writer alike.
TEST(Session, AVideoOutSessionCarriesItsMappingAndReadsBackTheDetectorImage) {
  TempDir dir;
  std::vector<cv::Mat> detector_images;
  auto s = small_session(detector_images);  // 60 x 40 detector
  geometry::VideoMapping m;
  m.video_cols = 100;
  m.video_rows = 140;
  m.image_rect = {10, 10, 80, 120};  // turned: 40 wide, 60 high, scaled by 2
  m.rotation_deg = 90;
  m.mirror = true;
  m.text_regions = {{0, 131, 100, 9}};
  s.video_mapping = m;
  const geometry::VideoToDetector map(m, 60, 40);
  std::vector<cv::Mat> smooth, video;
  for (const auto& d : detector_images) {
    cv::Mat picture;
    cv::GaussianBlur(d, picture, cv::Size(), 3.0);  // resampling needs a picture, not noise
    const auto& A = map.detector_to_video();
    const cv::Mat to_video = (cv::Mat_<double>(2, 3) << A(0, 0), A(0, 1), A(0, 2), A(1, 0), A(1, 1), A(1, 2));
    cv::Mat v;
    cv::warpAffine(picture, v, to_video, cv::Size(100, 140), cv::INTER_LINEAR);
    smooth.push_back(picture);
    video.push_back(v);
  }
  EXPECT_THROW(session::write_session(dir.path, s, detector_images), std::invalid_argument);
  session::write_session(dir.path, s, video);
  const auto r = session::read_session(dir.path);
  ASSERT_TRUE(r.video_mapping);
  EXPECT_EQ(geometry::video_mapping_json(*r.video_mapping), geometry::video_mapping_json(m));
  EXPECT_EQ(session::frame_size_px(r), std::make_pair(100, 140));
  const cv::Mat frame = session::read_session_frame(r, 1);
  EXPECT_EQ(frame.size(), cv::Size(100, 140));
  const cv::Mat detector = session::read_detector_frame(r, 1);
  ASSERT_EQ(detector.size(), cv::Size(60, 40));
  // The detector image again (resampled twice), and not the same image turned or mirrored.
  const auto mean_difference = [](const cv::Mat& a, const cv::Mat& b) {
    const cv::Rect inside(2, 2, a.cols - 4, a.rows - 4);
    cv::Mat fa, fb;
    a(inside).convertTo(fa, CV_64F);
    b(inside).convertTo(fb, CV_64F);
    return cv::mean(cv::abs(fa - fb))[0];
  };
  cv::Mat flipped;
  cv::flip(smooth[1], flipped, -1);
  EXPECT_LT(mean_difference(detector, smooth[1]), 0.1 * mean_difference(flipped, smooth[1]));
  cv::flip(smooth[1], flipped, 1);
  EXPECT_LT(mean_difference(detector, smooth[1]), 0.1 * mean_difference(flipped, smooth[1]));

  cv::imwrite((dir.path / "frames" / "f1.png").string(), detector_images[1]);
  try {
    session::read_session_frame(r, 1);
    FAIL() << "no error";
  } catch (const base::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("f1.png: 60 x 40 pixels, but the video mapping's frames are 100 x 140"),
              std::string::npos)
        << e.what();
  }
  s.video_mapping->image_rect = {10, 10, 80, 80};  // square: the turned detector is not
  EXPECT_THROW(session::write_session(dir.path / "bad", s, video), std::invalid_argument);
  replace_in(dir.path / "session.json", "120.0", "80.0");
  EXPECT_NE(error_reading(dir.path).find("session.json: video_mapping: does not fit the detector"), std::string::npos)
      << error_reading(dir.path);
}

// A session of a C-arm with zoom modes (issue 31): session.json lists them, carm.csv says each
// sample's, and a frame is the image of its mode (its view, its turn read back); what
// cannot be is refused by file, line and field.
TEST(Session, ZoomModesAndEachSamplesModeRoundTripAndWhatCannotBeIsNamed) {
  TempDir dir;
  std::vector<cv::Mat> images;
  auto s = small_session(images);  // 60 x 40 detector of 0.3 mm
  s.detector.col_spacing_mm = 0.3;
  const auto mode = [](int number, const std::string& name, double spacing_mm, int rotation_deg) {
    geometry::ZoomMode z = geometry::centred_zoom_mode(number, name, 60, 40, spacing_mm);
    z.rotation_deg = rotation_deg;
    return z;
  };
  s.zoom_modes = {mode(1, "18 cm", 0.3, 0), mode(2, "12 cm", 0.2, 180)};
  for (std::size_t k = 0; k < s.carm.size(); ++k) s.carm[k].zoom_mode = k < 2 ? 1 : 2;
  session::write_session(dir.path, s, images);
  {
    std::ifstream carm(dir.path / "carm.csv");
    std::string header;
    std::getline(carm, header);
    EXPECT_EQ(header.substr(header.size() - 10), ",zoom_mode");
  }
  const auto r = session::read_session(dir.path);
  ASSERT_EQ(r.zoom_modes.size(), 2u);
  EXPECT_EQ(geometry::zoom_modes_json(r.zoom_modes), geometry::zoom_modes_json(s.zoom_modes));
  for (std::size_t k = 0; k < r.carm.size(); ++k) EXPECT_EQ(r.carm[k].zoom_mode, s.carm[k].zoom_mode);
  EXPECT_EQ(session::frame_size_px(r), std::make_pair(60, 40));
  EXPECT_EQ(session::view_of(r, r.carm[0]).col_spacing_mm, 0.3);
  EXPECT_EQ(session::view_of(r, r.carm[3]).col_spacing_mm, 0.2);
  // Frame 0 was taken in mode 1 (as it is), frame 1 in mode 2, turned half round.
  EXPECT_EQ(cv::norm(session::read_detector_frame(r, 0), images[0], cv::NORM_INF), 0.0);
  cv::Mat turned_back;
  cv::flip(images[1], turned_back, -1);
  EXPECT_EQ(cv::norm(session::read_detector_frame(r, 1), turned_back, cv::NORM_INF), 0.0);
  // A PLUS sequence has one pixel size; these frames have two.
  try {
    session::export_plus_sequence(r, dir.path.parent_path() / "zoom.seq.mha");
    ADD_FAILURE() << "exported frames of two pixel sizes";
  } catch (const base::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("frame 2 was taken in zoom mode 2 (\"12 cm\"), whose pixels differ"), std::string::npos)
        << e.what();
  }

  // A mode the session does not list (the C-arm said it, the recording kept it): read, but
  // its frames have no known field, and whatever needs one says so by frame.
  replace_in(dir.path / "carm.csv", ",1,2\n", ",1,3\n");
  const auto unlisted = session::read_session(dir.path);
  EXPECT_EQ(unlisted.carm[3].zoom_mode, 3);
  EXPECT_FALSE(session::zoom_known(unlisted, unlisted.carm[3]));
  EXPECT_TRUE(session::zoom_known(unlisted, unlisted.carm[2]));
  EXPECT_THROW(session::view_of(unlisted, unlisted.carm[3]), std::invalid_argument);
  try {
    session::read_detector_frame(unlisted, 2);
    ADD_FAILURE() << "a frame of an unlisted mode was read as some detector's";
  } catch (const base::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("frame 3 was taken in zoom mode 3, which session.json's zoom_modes do not list"),
              std::string::npos) << e.what();
  }
  // Zoom modes listed, but carm.csv without the column that says which.
  auto plain = s;
  plain.zoom_modes.clear();
  for (auto& c : plain.carm) c.zoom_mode = 0;
  write_afresh(dir.path, plain, images);
  const std::string without = error_reading(dir.path);
  EXPECT_EQ(without, "no error");
  auto listed_json = nlohmann::json::parse(std::ifstream(dir.path / "session.json"));
  listed_json["zoom_modes"] = geometry::zoom_modes_json(s.zoom_modes);
  std::ofstream(dir.path / "session.json") << listed_json.dump(2);
  EXPECT_NE(error_reading(dir.path).find("carm.csv:1: header: session.json lists zoom_modes, so expected"), std::string::npos)
      << error_reading(dir.path);
  // A mode without zoom modes listed.
  write_afresh(dir.path, s, images);
  listed_json = nlohmann::json::parse(std::ifstream(dir.path / "session.json"));
  listed_json.erase("zoom_modes");
  std::ofstream(dir.path / "session.json") << listed_json.dump(2);
  EXPECT_NE(error_reading(dir.path).find("carm.csv:2: zoom_mode: 1, but session.json lists no zoom_modes"), std::string::npos)
      << error_reading(dir.path);
  // Modes whose frames differ in size cannot share a session's frames.
  auto sizes = s;
  sizes.zoom_modes[1].cols = 30;
  sizes.zoom_modes[1].width_mm = 30 * 0.2;
  try {
    write_afresh(dir.path, sizes, images);
    ADD_FAILURE() << "written";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("zoom_modes: zoom mode 2's frames are 30 x 40, zoom mode 1's 60 x 40"), std::string::npos)
        << e.what();
  }
}
