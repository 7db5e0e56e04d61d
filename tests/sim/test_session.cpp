#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "evar/geometry/input_error.hpp"
#include "evar/geometry/input_file.hpp"
#include "evar/sim/session.hpp"
#include "support/temp_dir.hpp"

using namespace evar;
namespace fs = std::filesystem;

namespace {

using evar::test::TempDir;

sim::Session small_session(std::vector<cv::Mat>& images) {
  sim::Session s;
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
    sim::CArmSample c;
    c.timestamp_ns = 990'000'000LL + k * 33'333'333LL;
    c.primary_deg = 30.0 + 0.1 * k + 1e-13;  // not representable in a few digits
    c.secondary_deg = -7.0 / 3.0;
    c.sid_mm = 1200.0;
    c.sod_mm = 785.5;
    c.table_mm = Eigen::Vector3d(0.1, -0.2, 1.0 / 3.0);
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

std::string error_reading(const fs::path& dir) {
  try {
    sim::read_session(dir);
  } catch (const geometry::InputError& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST(Session, RoundTripsBitExactly) {
  TempDir dir;
  std::vector<cv::Mat> images;
  const auto s = small_session(images);
  sim::write_session(dir.path, s, images);
  const auto r = sim::read_session(dir.path);
  EXPECT_EQ(r.scene, s.scene);
  EXPECT_EQ(r.ct_to_carm, s.ct_to_carm);
  EXPECT_EQ(r.device_thickness_mm, s.device_thickness_mm);
  ASSERT_EQ(r.frames.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(r.frames[i].frame, s.frames[i].frame);
    EXPECT_EQ(r.frames[i].timestamp_ns, s.frames[i].timestamp_ns);
    EXPECT_EQ(r.frames[i].source, s.frames[i].source);
    EXPECT_EQ(cv::norm(sim::read_session_frame(r, i), images[i], cv::NORM_INF), 0.0);
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

TEST(Session, GroundTruthRoundTripsAndItsErrorsAreNamed) {
  TempDir dir;
  std::vector<cv::Mat> images;
  auto s = small_session(images);
  fs::create_directories(dir.path / "patient" / "truth");
  std::ofstream(dir.path / "patient" / "truth" / "scene.json") << "{}";
  std::ofstream(dir.path / "patient" / "device.mrk.json") << "{}";
  s.truth = sim::SessionTruth{"patient/truth/scene.json", "patient/device.mrk.json", "truth/ostia_2d.csv",
                              {{1, "renal_left", {10.5, 20.0 / 3.0}}, {3, "internal_iliac_right", {-4.0, 1e-9}}}};
  sim::write_session(dir.path, s, images);
  const auto r = sim::read_session(dir.path);
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
  sim::write_session(dir.path, s, images);
  auto wrong = images;
  wrong[1] = cv::Mat(41, 60, CV_16UC1, cv::Scalar(5));
  EXPECT_THROW(sim::write_session(dir.path, s, wrong), std::invalid_argument);  // the writer refuses it too
  cv::imwrite((dir.path / "frames" / "f1.png").string(), wrong[1]);                // a file changed behind its back
  const auto r = sim::read_session(dir.path);
  try {
    sim::read_session_frame(r, 1);
    FAIL() << "no error";
  } catch (const geometry::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("f1.png: 60 x 41 pixels, but the detector is 60 x 40"), std::string::npos) << e.what();
  }
}

TEST(Session, CorruptFilesAreNamedWithTheirLine) {
  TempDir dir;
  std::vector<cv::Mat> images;
  const auto s = small_session(images);
  const auto fresh = [&] {
    fs::remove_all(dir.path);
    sim::write_session(dir.path, s, images);
  };
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

TEST(Session, TruncatedFilesAreClearErrorsAtEveryLength) {
  TempDir dir;
  std::vector<cv::Mat> images;
  const auto s = small_session(images);
  sim::write_session(dir.path, s, images);
  for (const char* name : {"session.json", "carm.csv", "frames/index.csv"}) {
    std::ifstream in(dir.path / name, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), {});
    for (std::size_t n = 0; n < bytes.size(); n += 7) {
      std::ofstream(dir.path / name, std::ios::binary | std::ios::trunc) << bytes.substr(0, n);
      try {
        sim::read_session(dir.path);  // a cut at a line end may still be a valid, shorter session
      } catch (const geometry::InputError&) {
      }
    }
    std::ofstream(dir.path / name, std::ios::binary | std::ios::trunc) << bytes;
  }
  std::ofstream(dir.path / "frames" / "f0.png", std::ios::binary | std::ios::trunc) << "\x89PNG garbage";
  const auto r = sim::read_session(dir.path);
  EXPECT_THROW(sim::read_session_frame(r, 0), geometry::InputError);
}

TEST(Session, ExportsAPlusSequenceMetafileForSlicer) {
  TempDir dir;
  std::vector<cv::Mat> images;
  const auto s = small_session(images);
  sim::write_session(dir.path / "s", s, images);
  const auto r = sim::read_session(dir.path / "s");
  sim::export_plus_sequence(r, dir.path / "run.seq.mha");
  std::ifstream in(dir.path / "run.seq.mha", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  const std::string marker = "ElementDataFile = LOCAL\n";
  const auto header_end = bytes.find(marker);
  ASSERT_NE(header_end, std::string::npos);
  const std::string header = bytes.substr(0, header_end);
  EXPECT_NE(header.find("DimSize = 60 40 3\n"), std::string::npos);
  EXPECT_NE(header.find("ElementType = MET_USHORT\n"), std::string::npos);
  EXPECT_NE(header.find("Seq_Frame0001_Timestamp = 0.066666667\n"), std::string::npos) << header;
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
  EXPECT_EQ(sim::carm_at(s, 0), &s.carm[0]);                   // before all: the first
  EXPECT_EQ(sim::carm_at(s, 1'023'333'333LL), &s.carm[1]);     // exactly at a sample
  EXPECT_EQ(sim::carm_at(s, 1'050'000'000LL), &s.carm[1]);
  EXPECT_EQ(sim::carm_at(s, 9'000'000'000LL), &s.carm[3]);     // after all: the last
  EXPECT_EQ(sim::carm_at(sim::Session{}, 5), nullptr);
}

TEST(Session, AnOversizedTableOrFrameIsRefusedByNameBeforeItIsRead) {
  TempDir dir;
  std::vector<cv::Mat> images;
  const auto s = small_session(images);
  sim::write_session(dir.path, s, images);
  fs::resize_file(dir.path / "carm.csv", geometry::kTableLimit.bytes + 1);  // sparse: no disk used
  EXPECT_NE(error_reading(dir.path).find("carm.csv: is 268435457 bytes, more than the 256 MiB accepted for a CSV table"),
            std::string::npos)
      << error_reading(dir.path);
  sim::write_session(dir.path, s, images);
  const auto r = sim::read_session(dir.path);
  fs::resize_file(dir.path / "frames" / "f0.png", geometry::kImageLimit.bytes + 1);
  try {
    sim::read_session_frame(r, 0);
    FAIL() << "no error";
  } catch (const geometry::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("f0.png: is 268435457 bytes, more than the 256 MiB accepted for an image file"),
              std::string::npos)
        << e.what();
  }
}
