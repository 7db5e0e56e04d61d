// `evarnode project`, `segment` and `reconstruct` on rendered views, and a reconstructed device driving `deform`.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "support/cli_fixture.hpp"
#include "evar/geometry/closest_point.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/ray_caster.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/geometry/xa_dicom.hpp"
#include "evar/sim/fluoro_render.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include "evar/geometry/video_mapping.hpp"
#include "support/video_out.hpp"
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <iterator>
#include <map>
#include "evar/session/session.hpp"
#include "evar/sim/example_scene.hpp"
#include "geometry/synthetic_fluoro.hpp"

namespace fs = std::filesystem;
using evar::test::Cli;
using evar::test::evarnode;
using evar::test::write_text;
using evar::app::run_cli;

TEST_F(Cli, ProjectPrintsPixelsAndWritesJson) {
  const auto dir = scratch("project");
  write_text(dir / "g.json", R"({"primary_angle_deg": 0, "secondary_angle_deg": 0, "source_to_detector_mm": 1200,
      "source_to_isocenter_mm": 800, "detector_size_px": [1000, 800], "pixel_spacing_mm": [0.3, 0.3]})");
  write_text(dir / "p.mrk.json", R"({"markups": [{"type": "Fiducial", "coordinateSystem": "LPS", "controlPoints": [
      {"label": "iso", "position": [0, 0, 0]}, {"label": "left", "position": [6, 0, 0]}]}]})");
  // CT origin 100 mm to the patient's right of the isocenter.
  write_text(dir / "t.json", R"({"matrix": [[1,0,0,-100],[0,1,0,0],[0,0,1,0],[0,0,0,1]]})");
  testing::internal::CaptureStdout();
  const int code = run_cli({"project", "--geometry", (dir / "g.json").string(), "--points", (dir / "p.mrk.json").string(),
                            "--out", (dir / "r.json").string()});
  const std::string table = testing::internal::GetCapturedStdout();
  ASSERT_EQ(code, 0);
  EXPECT_NE(table.find("499.50"), std::string::npos) << table;  // (cols − 1) / 2
  const auto r = nlohmann::json::parse(std::ifstream(dir / "r.json"));
  ASSERT_EQ(r["points"].size(), 2u);
  EXPECT_DOUBLE_EQ(r["points"][0]["pixel"][1].get<double>(), 399.5);
  // 6 mm at the isocenter, magnified 1.5, over 0.3 mm pixels: 30 px to the right.
  EXPECT_NEAR(r["points"][1]["pixel"][0].get<double>(), 529.5, 1e-9);
  EXPECT_EQ(r["points"][1]["where"], "on the detector");
  testing::internal::CaptureStdout();
  ASSERT_EQ(run_cli({"project", "--geometry", (dir / "g.json").string(), "--registration", (dir / "t.json").string(),
                     "--points", (dir / "p.mrk.json").string(), "--out", (dir / "r2.json").string()}),
            0);
  testing::internal::GetCapturedStdout();
  const auto r2 = nlohmann::json::parse(std::ifstream(dir / "r2.json"));
  EXPECT_NEAR(r2["points"][0]["pixel"][0].get<double>(), 499.5 - 100 * 1.5 / 0.3, 1e-9);
}

TEST_F(Cli, ProjectNamesABadGeometryField) {
  const auto dir = scratch("project_bad");
  write_text(dir / "g.json", R"({"primary_angle_deg": 0, "secondary_angle_deg": 0, "source_to_detector_mm": 700,
      "source_to_isocenter_mm": 800, "detector_size_px": [1000, 800], "pixel_spacing_mm": [0.3, 0.3]})");
  write_text(dir / "p.mrk.json", R"({"markups": [{"type": "Fiducial", "controlPoints": [{"position": [0, 0, 0]}]}]})");
  const auto run = evarnode({"project", "--geometry", (dir / "g.json").string(), "--points", (dir / "p.mrk.json").string()});
  EXPECT_EQ(run.code, 1);
  EXPECT_NE(run.err.find("g.json: source_to_isocenter_mm"), std::string::npos) << run.err;
}

TEST_F(Cli, ProjectReadsTheGeometryOfADicomFile) {
  const auto dir = scratch("project_dicom");
  evar::geometry::CArmView v;
  v.primary_angle_deg = 0;
  v.secondary_angle_deg = 0;
  v.source_to_detector_mm = 1200;
  v.source_to_isocenter_mm = 800;
  v.detector_cols = 100;
  v.detector_rows = 80;
  v.row_spacing_mm = v.col_spacing_mm = 0.3;
  evar::geometry::write_xa_dicom(dir / "view.img", v, {cv::Mat(80, 100, CV_16UC1, cv::Scalar(100))});
  write_text(dir / "p.mrk.json", R"({"markups": [{"type": "Fiducial", "controlPoints": [{"position": [0, 0, 0]}]}]})");
  testing::internal::CaptureStdout();
  const int code = run_cli({"project", "--geometry", (dir / "view.img").string(), "--points",
                            (dir / "p.mrk.json").string(), "--out", (dir / "r.json").string()});
  testing::internal::GetCapturedStdout();
  ASSERT_EQ(code, 0);
  const auto r = nlohmann::json::parse(std::ifstream(dir / "r.json"));
  EXPECT_DOUBLE_EQ(r["points"][0]["pixel"][0].get<double>(), 49.5);
}

namespace {
// Two rendered frames of a known wire, 30 degrees LAO and RAO, as PNG + geometry and DICOM.
struct TwoFrames {
  fs::path dir;
  evar::geometry::Polyline wire;
};
// The views the CLI tests render: 768² at 0.4 mm, SID 1200 mm, SOD 800 mm.
evar::geometry::CArmView test_view(double primary_deg) { return evar::test::detector_view(primary_deg, 0.0, 768, 0.4); }

TwoFrames write_two_frames(const fs::path& dir, double separation_deg = 60.0) {
  TwoFrames t{dir, evar::sim::iliac_guidewire()};
  for (int k = 0; k < 2; ++k) {
    const evar::geometry::CArmView v = test_view((k == 0 ? 0.5 : -0.5) * separation_deg);
    evar::sim::FluoroOptions o;
    o.seed = static_cast<std::uint64_t>(k + 1);
    const auto f = evar::sim::render_fluoro(evar::geometry::projection_matrix(v), v, {t.wire}, o);
    const std::string n = std::to_string(k + 1);
    cv::imwrite((dir / ("view" + n + ".png")).string(), f.image);
    evar::geometry::write_view_geometry(dir / ("view" + n + ".json"), v);
    evar::geometry::write_xa_dicom(dir / ("view" + n + ".dcm"), v, {f.image}, k == 1, 12);
  }
  return t;
}
}  // namespace

TEST_F(Cli, SegmentWritesTheCurveAndSaysWhenThereIsNone) {
  const auto dir = scratch("segment");
  write_two_frames(dir);
  ASSERT_EQ(evarnode({"segment", "--image", (dir / "view1.png").string(), "--geometry", (dir / "view1.json").string(),
                      "--out", (dir / "d.json").string(), "--overlay", (dir / "o.png").string()})
                .code,
            0);
  const auto j = nlohmann::json::parse(std::ifstream(dir / "d.json"));
  EXPECT_TRUE(j["found"].get<bool>());
  EXPECT_GT(j["points_px"].size(), 100u);
  EXPECT_NEAR(j["device_width_px"].get<double>(), 0.89 * 1.5 / 0.4, 1e-9);
  EXPECT_TRUE(fs::exists(dir / "o.png"));
  cv::imwrite((dir / "blank.png").string(), cv::Mat(200, 200, CV_16UC1, cv::Scalar(3000)));
  const auto none = evarnode({"segment", "--image", (dir / "blank.png").string(), "--out", (dir / "n.json").string()});
  EXPECT_EQ(none.code, 3);
  EXPECT_NE(none.err.find("no device found"), std::string::npos) << none.err;
  EXPECT_FALSE(nlohmann::json::parse(std::ifstream(dir / "n.json"))["found"].get<bool>());
  write_text(dir / "junk.png", "not an image");
  EXPECT_EQ(evarnode({"segment", "--image", (dir / "junk.png").string(), "--out", (dir / "x.json").string()}).code, 1);
}


// Frames in a C-arm's video-out form (each view's 768² detector image shown 1.33 times
// larger in a 1280 x 1024 frame with black borders, one turned a quarter and mirrored), their
// view geometry carrying the video mapping: reconstruct reads the detector image back through
// it and finds the wire as from the detector's own frames; project gives the video pixel
// beside the detector's; a frame of another size than the mapping's is refused by name.
TEST_F(Cli, VideoOutFramesWithTheirMappingReconstructAsTheDetectorsOwn) {
  const auto dir = scratch("video_out");
  const auto t = write_two_frames(dir);
  std::vector<evar::geometry::VideoMapping> mappings;
  for (const int k : {1, 2}) {
    const std::string n = std::to_string(k);
    const auto view = evar::geometry::read_view_geometry(dir / ("view" + n + ".json"));
    evar::geometry::VideoMapping m;
    m.video_cols = 1280;
    m.video_rows = 1024;
    m.image_rect = {128, 0, 1024, 1024};
    m.rotation_deg = k == 1 ? 90 : 0;
    m.mirror = k == 1;
    m.text_regions = {{0, 0, 120, 40}};
    mappings.push_back(m);
    cv::imwrite((dir / ("video" + n + ".png")).string(),
                evar::test::shown_on_monitor(cv::imread((dir / ("view" + n + ".png")).string(), cv::IMREAD_UNCHANGED), m));
    evar::geometry::write_view_geometry(dir / ("video" + n + ".json"), view, m);
  }
  std::vector<std::string> args{"reconstruct", "--out", (dir / "device.mrk.json").string()};
  for (const char* n : {"1", "2"})
    args.insert(args.end(), {"--image", (dir / (std::string("video") + n + ".png")).string(), "--geometry",
                             (dir / (std::string("video") + n + ".json")).string()});
  const auto run = evarnode(args);
  ASSERT_EQ(run.code, 0) << run.err;
  const auto curve = evar::geometry::read_curve(dir / "device.mrk.json", 2);
  double sum = 0.0;
  for (const auto& p : curve.points) sum += evar::geometry::project_onto(t.wire, p.position_lps).distance_mm;
  EXPECT_LT(sum / static_cast<double>(curve.points.size()), 1.0);  // as from the detector's frames
  EXPECT_LT((curve.points.front().position_lps - t.wire.front()).norm(), 3.0);

  write_text(dir / "tip.mrk.json", R"({"markups": [{"type": "Fiducial", "coordinateSystem": "LPS", "controlPoints": [
      {"label": "tip", "position": [)" + std::to_string(t.wire.front().x()) + ", " + std::to_string(t.wire.front().y()) +
                                         ", " + std::to_string(t.wire.front().z()) + "]}]}]}");
  testing::internal::CaptureStdout();
  ASSERT_EQ(run_cli({"project", "--geometry", (dir / "video1.json").string(), "--points", (dir / "tip.mrk.json").string(),
                     "--out", (dir / "r.json").string()}),
            0);
  testing::internal::GetCapturedStdout();
  const auto r = nlohmann::json::parse(std::ifstream(dir / "r.json"));
  const Eigen::Vector2d pixel(r["points"][0]["pixel"][0].get<double>(), r["points"][0]["pixel"][1].get<double>());
  const Eigen::Vector2d shown = evar::geometry::VideoToDetector(mappings[0], 768, 768).to_video(pixel);
  EXPECT_NEAR(r["points"][0]["video_pixel"][0].get<double>(), shown.x(), 1e-9);
  EXPECT_NEAR(r["points"][0]["video_pixel"][1].get<double>(), shown.y(), 1e-9);
  // Turned a quarter clockwise and mirrored, the detector's u runs down the frame.
  EXPECT_NEAR(shown.y(), (pixel.x() + 0.5) * 1024.0 / 768.0 - 0.5, 1e-9);

  const auto wrong = evarnode({"segment", "--image", (dir / "view1.png").string(), "--geometry",
                               (dir / "video1.json").string(), "--out", (dir / "d.json").string()});
  EXPECT_EQ(wrong.code, 1);
  EXPECT_NE(wrong.err.find("video_mapping.video_size_px is 1280 x 1024 but"), std::string::npos) << wrong.err;
}

TEST_F(Cli, ReconstructFromPngsAndFromDicomMatchesTheWire) {
  const auto dir = scratch("reconstruct");
  const auto t = write_two_frames(dir);
  for (const bool dicom : {false, true}) {
    std::vector<std::string> args{"reconstruct", "--out", (dir / "device.mrk.json").string(), "--report",
                                  (dir / "r.json").string()};
    for (const char* n : {"1", "2"}) {
      args.insert(args.end(), {"--image", (dir / (std::string("view") + n + (dicom ? ".dcm" : ".png"))).string()});
      if (!dicom) args.insert(args.end(), {"--geometry", (dir / (std::string("view") + n + ".json")).string()});
    }
    const auto run = evarnode(args);
    ASSERT_EQ(run.code, 0) << run.err;
    const auto curve = evar::geometry::read_curve(dir / "device.mrk.json", 2);
    double sum = 0.0;
    for (const auto& p : curve.points) sum += evar::geometry::project_onto(t.wire, p.position_lps).distance_mm;
    EXPECT_LT(sum / static_cast<double>(curve.points.size()), 1.0) << (dicom ? "DICOM" : "PNG");
    EXPECT_LT((curve.points.front().position_lps - t.wire.front()).norm(), 3.0);  // tip first
    const auto report = nlohmann::json::parse(std::ifstream(dir / "r.json"));
    EXPECT_NEAR(report["separation_deg"].get<double>(), 60.0, 1e-6);
  }
}

TEST_F(Cli, ReconstructRefusesViewsTooCloseTogether) {
  const auto dir = scratch("reconstruct_close");
  write_two_frames(dir, 12.0);
  const auto run = evarnode({"reconstruct", "--image", (dir / "view1.dcm").string(), "--image", (dir / "view2.dcm").string(),
                             "--out", (dir / "d.mrk.json").string(), "--report", (dir / "r.json").string()});
  EXPECT_EQ(run.code, 1);
  EXPECT_NE(run.err.find("degrees apart"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir / "d.mrk.json"));
  EXPECT_TRUE(nlohmann::json::parse(std::ifstream(dir / "r.json")).contains("error"));
}

// The whole chain on files: two simulated frames of the example's guidewire, registered to
// the C-arm with its sac at the isocenter → reconstruct (into CT LPS) → deform.
TEST_F(Cli, ReconstructedDeviceDrivesTheDeformation) {
  const auto dir = scratch("chain");
  evar::sim::ExampleSceneParams p;
  p.aorta_vertices = 2500;
  p.iliac_vertices = 1500;
  const auto example = evar::sim::make_example_scene(p);
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.block<3, 1>(0, 3) = -Eigen::Vector3d(0, 0, p.aneurysm_centre_z_mm);  // CT → C-arm: sac centre at the isocenter
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
  write_text(dir / "T.json", nlohmann::json{{"matrix", rows}}.dump());
  evar::geometry::Polyline wire;
  for (const auto& d : example.device) wire.push_back((T * d.homogeneous()).head<3>());
  for (int k = 0; k < 2; ++k) {
    const evar::geometry::CArmView v = test_view(k == 0 ? 35 : -35);
    evar::sim::FluoroOptions o;
    o.seed = static_cast<std::uint64_t>(k + 7);
    const auto f = evar::sim::render_fluoro(evar::geometry::projection_matrix(v), v, {wire}, o);
    evar::geometry::write_xa_dicom(dir / (k == 0 ? "v0.dcm" : "v1.dcm"), v, {f.image}, false, 12);
  }
  const auto rec = evarnode({"reconstruct", "--image", (dir / "v0.dcm").string(), "--image", (dir / "v1.dcm").string(),
                             "--registration", (dir / "T.json").string(), "--out", (dir / "device.mrk.json").string()});
  ASSERT_EQ(rec.code, 0) << rec.err;
  // In CT coordinates again, on the example's own device.
  const auto curve = evar::geometry::read_curve(dir / "device.mrk.json", 2);
  double sum = 0.0;
  for (const auto& q : curve.points) sum += evar::geometry::project_onto(example.device, q.position_lps).distance_mm;
  EXPECT_LT(sum / static_cast<double>(curve.points.size()), 1.0);
  const auto def = evarnode({"deform", "--scene", scene().string(), "--device", (dir / "device.mrk.json").string(), "--out",
                             (dir / "deformed").string(), "--no-preview"});
  ASSERT_EQ(def.code, 0) << def.err;
  const auto report = nlohmann::json::parse(std::ifstream(dir / "deformed" / "report.json"));
  int control_points = 0;
  for (const auto& v : report["vessels"]) control_points += v["control_points"].get<int>();
  EXPECT_GT(control_points, 0);
}

// The evaluation loop a research user runs: a synthetic patient, deform it, compare with
// its truth. The carrier's internal iliac ostium must end closer to its true position.
