// Sessions on the command line: `sim`, `eval`, `replay`, `export`, `run --replay`, `record --recover`.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "node_config.hpp"
#include "support/cli_fixture.hpp"
#include "evar/geometry/closest_point.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/geometry/mesh_io.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/ray_caster.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/geometry/xa_dicom.hpp"
#include "evar/sim/fluoro_render.hpp"
#include "evar/sim/monitor_picture.hpp"
#include "evar/geometry/video_mapping.hpp"

#include <opencv2/imgcodecs.hpp>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <iterator>
#include <map>
#include "evar/session/session.hpp"
#include "evar/sim/example_scene.hpp"
#include "geometry/synthetic_fluoro.hpp"
#include "support/killed_recording.hpp"
#include "support/ramp_frames.hpp"

namespace fs = std::filesystem;
using evar::test::Cli;
using evar::test::evarnode;
using evar::test::write_text;
using evar::app::run_cli;

TEST_F(Cli, SimPatientFeedsDeformAndItsTruthIsComparable) {
  const auto out = scratch("sim_patient");
  ASSERT_EQ(evarnode({"sim", "patient", "--seed", "5", "--out", (out / "p").string(), "--aorta-vertices", "3000",
                      "--iliac-vertices", "1500"}).code, 0);
  for (const char* f : {"scene.json", "device.mrk.json", "patient.json", "truth/scene.json", "truth/landmarks.mrk.json"})
    EXPECT_TRUE(fs::exists(out / "p" / f)) << f;
  ASSERT_EQ(evarnode({"deform", "--scene", (out / "p/scene.json").string(), "--device", (out / "p/device.mrk.json").string(),
                      "--out", (out / "r").string(), "--no-preview"}).code, 0);
  const auto carrier = nlohmann::json::parse(std::ifstream(out / "p/patient.json"))["ground_truth"]["carrier"].get<std::string>();
  const std::string label = carrier == "iliac_left" ? "internal_iliac_left" : "internal_iliac_right";
  const auto at = [&](const fs::path& file) {
    for (const auto& m : evar::geometry::read_markups(file))
      for (const auto& p : m.points)
        if (p.label == label) return p.position_lps;
    ADD_FAILURE() << label << " not in " << file;
    return Eigen::Vector3d::Zero().eval();
  };
  const Eigen::Vector3d truth = at(out / "p/truth/landmarks.mrk.json");
  const double before = (at(out / "p/landmarks.mrk.json") - truth).norm();
  const double after = (at(out / "r/landmarks.mrk.json") - truth).norm();
  EXPECT_GT(before, 2.0);  // the device really moves it
  EXPECT_LT(after, 0.5 * before);
}

// `eval`, the paper's Table 1 on a simulated session with ground truth: the carrier's
// internal iliac ostium comes much closer, none gets worse, and the device the node
// reconstructed is measured against the true one in 3D.
TEST_F(Cli, EvalMeasuresTheOstiaBeforeAndAfterAndTheReconstructedDevice) {
  const auto out = scratch("eval");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "1", "--detector-px", "256", "--out", (out / "s1").string()}).code, 0);
  const auto r = evarnode({"eval", (out / "s1").string(), "--out", (out / "e").string()});
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* f : {"eval.json", "eval.md", "per_case.png", "distribution.png"}) EXPECT_TRUE(fs::exists(out / "e" / f)) << f;
  const auto j = nlohmann::json::parse(std::ifstream(out / "e" / "eval.json"));
  ASSERT_EQ(j["cases"].size(), 1u);
  const auto& c = j["cases"][0];
  const std::string carrier =
      nlohmann::json::parse(std::ifstream(out / "s1" / "patient" / "patient.json"))["ground_truth"]["carrier"];
  const std::string carrier_ostium = carrier == "iliac_left" ? "internal_iliac_left" : "internal_iliac_right";
  ASSERT_EQ(c["landmarks"].size(), 4u);  // two renal and two internal iliac ostia, each seen
  EXPECT_EQ(c["device_iliac"], carrier) << "the iliac the true device runs in";
  bool saw_carrier = false;
  for (const auto& l : c["landmarks"]) {
    const double before = l["initial_mm"], after = l["adapted_mm"];
    EXPECT_GT(l["frames"].get<int>(), 20) << l["label"];
    EXPECT_LT(after, before + 0.5) << l["label"] << " got worse";
    EXPECT_EQ(l["on_device_vessel"].get<bool>(), l["label"] == carrier_ostium) << l["label"];
    if (l["label"] == carrier_ostium) {
      saw_carrier = true;
      EXPECT_EQ(l["vessel"], carrier);
      EXPECT_GT(before, 1.0) << "the device does not move the carrier's ostium: nothing to measure";
      EXPECT_LT(after, 0.5 * before) << l["label"];
    }
  }
  EXPECT_TRUE(saw_carrier) << carrier_ostium;
  EXPECT_LT(j["summary"]["euclidean"]["adapted"]["mean_mm"].get<double>(),
            j["summary"]["euclidean"]["initial"]["mean_mm"].get<double>());
  // The paper's protocol (its Table 1): the ostia on the iliac carrying the device.
  const auto& paper = j["summary"]["device_iliac_ostia"]["euclidean"];
  EXPECT_EQ(paper["initial"]["n"], 1);
  EXPECT_LT(paper["adapted"]["mean_mm"].get<double>(), 0.5 * paper["initial"]["mean_mm"].get<double>());
  // The reconstruction from two 256 x 256 views (1.2 mm pixels, 0.8 mm at the isocenter):
  // sub-pixel curves put the device within half an isocenter pixel on average (measured
  // 0.15 mm), its worst point (the tip, where the two views' ends differ) within two.
  const auto& d = j["summary"]["device_reconstruction"];
  EXPECT_GE(d["models"].get<int>(), 1);
  EXPECT_EQ(c["device_errors"].size(), d["models"].get<std::size_t>());
  EXPECT_GT(d["mean_mm"].get<double>(), 0.0);
  EXPECT_LT(d["mean_mm"].get<double>(), 0.4);
  EXPECT_LT(d["worst_point_mm"].get<double>(), 1.6);
  // How much of the wire it spans: the part in both views, less than the whole wire (which
  // runs on to the access outside the field of view) and more than a sliver.
  for (const auto& e : c["device_errors"]) {
    EXPECT_GT(e["covered_mm"].get<double>(), 50.0);
    EXPECT_LT(e["covered_mm"].get<double>(), e["true_length_mm"].get<double>());
  }
  // Both devices, for Slicer or `deform --device`: the reconstructed one first.
  const auto devices = nlohmann::json::parse(std::ifstream(out / "e" / "devices" / "01-s1.mrk.json"));
  ASSERT_EQ(devices["markups"].size(), 2u);
  EXPECT_EQ(devices["markups"][0]["name"], "reconstructed device");
  EXPECT_EQ(devices["markups"][0]["controlPoints"].size(), c["model"]["device_points"].get<std::size_t>());
  EXPECT_EQ(devices["markups"][1]["name"], "true device");
  std::ifstream md(out / "e" / "eval.md");
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("Reconstructed device against the true device"), std::string::npos) << text;
}

// At the paper's difficulty the registration given to the node is off by a residual: eval
// still measures the reconstructed device against the true one in the node's frame (a
// device compared across the residual would be millimetres off), says which physics and
// difficulty each case is, and reports each physics on its own.
TEST_F(Cli, EvalOfAPaperDifficultySessionReportsItsPhysicsAndTheResidual) {
  const auto out = scratch("eval_paper");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "3", "--difficulty", "paper", "--physics", "conforming", "--detector-px",
                      "256", "--fluoro-seconds", "1", "--out", (out / "s").string()})
                .code,
            0);
  const auto r = evarnode({"eval", (out / "s").string(), "--out", (out / "e").string(), "--no-progress"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(std::ifstream(out / "e" / "eval.json"));
  const auto& c = j["cases"][0];
  EXPECT_EQ(c["physics"], "conforming");
  EXPECT_EQ(c["difficulty"], "paper");
  EXPECT_GT(c["registration_residual_deg"].get<double>(), 0.1);
  EXPECT_LT(c["registration_residual_deg"].get<double>(), 5.0 * std::sqrt(3.0));
  ASSERT_TRUE(j["summary"]["by_physics"].contains("conforming physics, paper difficulty")) << j["summary"].dump();
  EXPECT_LT(j["summary"]["device_reconstruction"]["mean_mm"].get<double>(), 0.4);
  for (const auto& l : c["landmarks"])
    if (l["label"].get<std::string>().rfind("renal", 0) == 0) {
      EXPECT_LT(l["initial_mm"].get<double>(), 3.0) << l["label"];
    }
  std::ifstream md(out / "e" / "eval.md");
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("## conforming physics, paper difficulty"), std::string::npos) << text;
  // As the node, eval registers the patient's pelvis (in its scene) from the fluoroscopy
  // views and says what it found in each; with --no-pelvis the models stay where the
  // registration put them.
  const auto plain = evarnode({"eval", (out / "s").string(), "--out", (out / "e-plain").string(), "--no-progress", "--no-pelvis"});
  ASSERT_EQ(plain.code, 0) << plain.err;
  EXPECT_TRUE(nlohmann::json::parse(std::ifstream(out / "e-plain" / "eval.json"))["cases"][0]["pelvis"].is_null());
  const auto& p = c["pelvis"];
  ASSERT_TRUE(p.is_object()) << p.dump();
  EXPECT_GE(p["views"].size(), 2u);
  ASSERT_TRUE(p["found"].get<bool>()) << p.dump();
  // Where the pose puts the internal iliac ostia's pelvis against where it truly lies: the
  // true registration, the one given to the node and the posture's shift of the pelvis.
  const auto matrix = [](const fs::path& f) {
    const auto j = nlohmann::json::parse(std::ifstream(f))["matrix"];
    Eigen::Matrix4d m;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) m(r, c) = j[r][c].get<double>();
    return m;
  };
  const Eigen::Matrix4d M = matrix(out / "s" / "registration.json").inverse() * matrix(out / "s" / "truth" / "registration.json");
  const auto shift_json = nlohmann::json::parse(std::ifstream(out / "s" / "patient" / "patient.json"))["posture_change"]["pelvis_shift_mm"];
  const Eigen::Vector3d shift(shift_json[0].get<double>(), shift_json[1].get<double>(), shift_json[2].get<double>());
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R(r, c) = p["rotation"][r][c].get<double>();
  const Eigen::Vector3d pivot(p["pivot_mm"][0].get<double>(), p["pivot_mm"][1].get<double>(), p["pivot_mm"][2].get<double>());
  const Eigen::Vector3d found_shift(p["shift_mm"][0].get<double>(), p["shift_mm"][1].get<double>(), p["shift_mm"][2].get<double>());
  int ostia = 0;
  for (const auto& lm : evar::geometry::read_fiducials(out / "s" / "patient" / "landmarks.mrk.json")) {
    if (lm.label.rfind("internal_iliac", 0) != 0) continue;
    ++ostia;
    const Eigen::Vector3d x = lm.position_lps;
    const Eigen::Vector3d truth = (M * (x + shift).homogeneous()).head<3>();
    const Eigen::Vector3d found = R * (x - pivot) + pivot + found_shift;
    // 2.3 and 1.7 mm here, on 256-pixel frames (0.8 mm at the isocenter): within 5 pixels,
    // and within a quarter of how far the pelvis truly lies from where it was registered.
    EXPECT_LT((found - truth).norm(), 4.0) << lm.label;
    EXPECT_LT((found - truth).norm(), 0.25 * (truth - x).norm()) << lm.label << ": truth moved " << (truth - x).norm() << " mm";
  }
  EXPECT_EQ(ostia, 2);
  // The node's report says what it did with the pelvis (the node itself:
  // tests/node/test_live_node_pelvis.cpp).
  const auto run = evarnode({"run", "--replay", (out / "s").string(), "--speed", "4", "--no-video", "--no-igtl", "--out",
                             (out / "run").string(), "--no-progress"});
  ASSERT_EQ(run.code, 0) << run.err;
  const auto pelvis = nlohmann::json::parse(std::ifstream(out / "run" / "run_report.json"))["pelvis"];
  EXPECT_TRUE(pelvis["looked_for"].get<bool>()) << pelvis.dump();
  EXPECT_GE(pelvis["views"].get<int>(), 2) << pelvis.dump();
  EXPECT_GE(pelvis["registrations"].get<int>(), 1) << pelvis.dump();
  EXPECT_FALSE(pelvis["last"].get<std::string>().empty()) << pelvis.dump();
  EXPECT_NE(run.err.find("pelvis"), std::string::npos) << run.err;
}

// A recording without ground truth cannot be evaluated: said with the file and the field.
TEST_F(Cli, EvalOfASessionWithoutGroundTruthNamesTheField) {
  const auto out = scratch("eval_no_truth");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "2", "--detector-px", "256", "--out", (out / "s").string()}).code, 0);
  auto j = nlohmann::json::parse(std::ifstream(out / "s" / "session.json"));
  j.erase("ground_truth");
  std::ofstream(out / "s" / "session.json") << j.dump(2);
  const auto r = evarnode({"eval", (out / "s").string(), "--out", (out / "e").string()});
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("session.json"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("ground_truth"), std::string::npos) << r.err;
}

// Seed 7's tortuous iliac, pushed into a tight bend, was refused at first and then
// made with an extra pass on the meshes; both came from the inside test's repeated hits
// (since fixed). Its truth holds the device in the distorted vessels, checked here
// on the written files: every device point inside a truth mesh or within Δd of a wall.
TEST_F(Cli, SimPatientSeed7HoldsTheDeviceInItsTruth) {
  const auto out = scratch("sim_patient_seed7");
  const auto r = evarnode({"sim", "patient", "--seed", "7", "--out", out.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto truth = evar::geometry::load_scene(out / "truth" / "scene.json");
  std::vector<evar::geometry::RayCaster> casters;
  for (const auto& v : truth.vessels) casters.emplace_back(v.mesh.mesh);
  const auto device = evar::geometry::read_curve(out / "truth" / "device.mrk.json").points;
  ASSERT_GT(device.size(), 50u);
  for (const auto& d : device) {
    bool held = false;
    for (std::size_t i = 0; i < casters.size() && !held; ++i)
      held = casters[i].contains(d.position_lps) ||
             evar::geometry::closest_point_on_mesh(truth.vessels[i].mesh.mesh, d.position_lps).distance_mm <=
                 truth.device_thickness_mm;
    EXPECT_TRUE(held) << d.position_lps.transpose();
  }
  const auto j = nlohmann::json::parse(std::ifstream(out / "patient.json"));
  EXPECT_GE(j["ground_truth"]["mesh_passes"].get<int>(), 0);
}

// A simulated intervention, replayed through the acquisition interfaces: every frame
// arrives, none while the C-arm moves, in the three views the session was made in.
TEST_F(Cli, SimSessionThenReplayDeliversEveryFrameInItsViews) {
  const auto out = scratch("sim_session");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "2", "--out", (out / "s").string(), "--detector-px", "96",
                      "--fluoro-seconds", "0.2", "--no-progress"}).code, 0);
  ASSERT_EQ(evarnode({"replay", (out / "s").string(), "--fast", "--loop", "2", "--no-progress", "--report",
                      (out / "r.json").string()}).code, 0);
  const auto r = nlohmann::json::parse(std::ifstream(out / "r.json"));
  // 3 runs of 3 fluoroscopy frames and 12 DSA frames (4 fps for 3 s), twice.
  EXPECT_EQ(r["frames"], 2 * (9 + 12));
  EXPECT_EQ(r["dropped"], 0);
  EXPECT_EQ(r["frames_while_moving"], 0);
  EXPECT_GT(r["carm_moving_states"].get<int>(), 0);
  EXPECT_EQ(r["frames_per_view"].size(), 3u);
  EXPECT_EQ(r["error"], "");
}

TEST_F(Cli, ExportWritesASlicerSequenceOfEveryFrameAndNothingWhenAFrameDoesNotFit) {
  const auto out = scratch("export");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "2", "--out", (out / "s").string(), "--detector-px", "64",
                      "--fluoro-seconds", "0.2", "--no-progress"}).code, 0);
  const auto r = evarnode({"export", (out / "s").string(), "--out", (out / "run.seq.mha").string(), "--no-progress"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("wrote " + (out / "run.seq.mha").string() + ": 21 frames of 64 x 64"), std::string::npos) << r.err;
  // 9 fluoroscopy and 12 DSA frames, each 64 x 64 x 2 bytes after the header.
  std::ifstream in(out / "run.seq.mha", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  const auto data = bytes.find("ElementDataFile = LOCAL\n");
  ASSERT_NE(data, std::string::npos);
  EXPECT_NE(bytes.find("DimSize = 64 64 21\n"), std::string::npos);
  EXPECT_EQ(bytes.size() - data - std::string("ElementDataFile = LOCAL\n").size(), 21u * 64u * 64u * 2u);
  EXPECT_NE(bytes.find("Seq_Frame0020_Source = dsa\n"), std::string::npos);

  // A frame of another size: refused by name, and no sequence (nor a partial one) is left.
  cv::imwrite((out / "s" / "frames" / "000005.png").string(), cv::Mat(32, 64, CV_16UC1, cv::Scalar(100)));
  const auto bad = evarnode({"export", (out / "s").string(), "--out", (out / "bad.seq.mha").string(), "--no-progress"});
  EXPECT_EQ(bad.code, 1);
  EXPECT_NE(bad.err.find("000005.png: 64 x 32 pixels, but the detector is 64 x 64"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(out / "bad.seq.mha"));
  EXPECT_FALSE(fs::exists(out / "bad.seq.mha.partial"));
  // A name Slicer would not recognise is written, with a warning saying so.
  const auto plain = evarnode({"export", (out / "s").string(), "--out", (out / "run.mha").string(), "--no-progress"});
  EXPECT_EQ(plain.code, 1);  // the bad frame is still there
  EXPECT_NE(plain.err.find("recognises sequence metafiles by the name *.seq.mha"), std::string::npos) << plain.err;
}

TEST_F(Cli, ReplayOfACorruptSessionNamesTheFileAndLine) {
  const auto out = scratch("replay_corrupt");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "2", "--out", out.string(), "--detector-px", "64", "--fluoro-seconds", "0.1",
                      "--no-progress"}).code, 0);
  std::ofstream(out / "carm.csv", std::ios::app) << "12,0,0,1200,80x0,0,0,0,1,0\n";
  const auto r = evarnode({"replay", out.string(), "--fast", "--no-progress"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("carm.csv:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("sod_mm: '80x0' is not a number"), std::string::npos) << r.err;
}

// `export --out SESSION/carm.csv` overwrote the session's own C-arm stream with the sequence.
TEST_F(Cli, ExportRefusesAnOutputInsideTheSession) {
  const auto out = scratch("export_inside");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "2", "--out", (out / "s").string(), "--detector-px", "64",
                      "--fluoro-seconds", "0.1", "--no-progress"}).code, 0);
  std::ifstream in(out / "s" / "carm.csv", std::ios::binary);
  const std::string carm((std::istreambuf_iterator<char>(in)), {});
  const auto r = evarnode({"export", (out / "s").string(), "--out", (out / "s" / "carm.csv").string(), "--no-progress"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("carm.csv: is inside the session directory"), std::string::npos) << r.err;
  std::ifstream again(out / "s" / "carm.csv", std::ios::binary);
  EXPECT_EQ(std::string((std::istreambuf_iterator<char>(again)), {}), carm);
  EXPECT_EQ(evarnode({"export", (out / "s").string(), "--out", (out / "s" / "frames" / "run.seq.mha").string(),
                      "--no-progress"}).code, 1);
  EXPECT_FALSE(fs::exists(out / "s" / "frames" / "run.seq.mha"));
}

// `run --speed` had no lower bound: at 1e-12 the wait for a frame overflowed the clock.
TEST_F(Cli, RunTakesTheReplaysSpeedRange) {
  const auto out = scratch("run_speed");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "2", "--out", (out / "s").string(), "--detector-px", "64",
                      "--fluoro-seconds", "0.1", "--no-progress"}).code, 0);
  for (const std::string speed : {"1e-12", "0.001", "5000"})
    EXPECT_EQ(evarnode({"run", "--replay", (out / "s").string(), "--speed", speed, "--out", (out / "run").string(),
                        "--no-video", "--no-igtl", "--seconds", "1", "--no-progress"}).code, 2)
        << speed;
}

// A recorder killed mid-recording (here by SIGKILL) leaves frames and its journal; `record
// --recover` makes them a session `replay` takes.
TEST_F(Cli, RecordRecoverMakesASessionOfAKilledRecording) {
  const auto out = scratch("record_recover");
  evar::session::Session original;
  original.scene = "scene.json";
  original.detector = {32, 24, 0.3, 0.3};
  const auto images = evar::test::add_ramp_frames(original, 6, 50'000'000LL, {3000, 11, 7, 2});
  for (int k = 0; k < 3; ++k) {
    evar::session::CArmSample c;
    c.timestamp_ns = 990'000'000LL + k * 100'000'000LL;
    c.primary_deg = 15.0 * k;
    c.sid_mm = 1200;
    c.sod_mm = 800;
    c.fluoro_on = true;
    original.carm.push_back(c);
  }
  evar::session::write_session(out / "original", original, images);
  evar::session::RecorderOptions o;
  o.out = out / "recorded";
  o.scene = scene();
  o.pixel_spacing_mm = 0.2;
  const int status = evar::test::record_then_kill(o, evar::session::read_session(out / "original"));
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "child status " << status;

  const auto r = evarnode({"record", "--recover", o.out.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("6 frames and 3 C-arm states recovered"), std::string::npos) << r.err;
  const auto replayed = evarnode({"replay", o.out.string(), "--fast", "--no-progress"});
  EXPECT_EQ(replayed.code, 0) << replayed.err;
  EXPECT_NE(replayed.err.find("6 frames (0 dropped) and 3 C-arm states"), std::string::npos) << replayed.err;

  const auto again = evarnode({"record", "--recover", o.out.string()});
  EXPECT_EQ(again.code, 1);
  EXPECT_NE(again.err.find("a finished session"), std::string::npos) << again.err;
  // --recover stands alone; a recording needs its options.
  EXPECT_EQ(evarnode({"record", "--recover", o.out.string(), "--carm", "serial:/dev/null"}).code, 2);
  const auto missing = evarnode({"record", "--scene", scene().string(), "--out", (out / "x").string()});
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.err.find("--carm"), std::string::npos) << missing.err;
}

// Each side may be up to 16384 px, but no session holds frames of more than 8192 x 8192 in
// all: a size its frames could never be written at is refused before anything is opened.
TEST_F(Cli, RecordRefusesAFrameSizeNoSessionCanHold) {
  const auto out = scratch("record_big");
  const auto args = [&](const char* w, const char* h) {
    return std::vector<std::string>{"record", "--camera", "NONE", "--carm", "serial:/dev/null", "--scene",
                                    scene().string(), "--registration", scene().string(), "--pixel-spacing", "0.3",
                                    "--out", (out / "big").string(), "--width", w, "--height", h};
  };
  const auto big = evarnode(args("16384", "8193"));
  EXPECT_EQ(big.code, 2);
  EXPECT_NE(big.err.find("16384 x 8193 pixels; a session's frames hold at most 67108864 in all"), std::string::npos)
      << big.err;
  EXPECT_FALSE(fs::exists(out / "big"));
  // 16384 x 4096 is within the limit: it gets past the options (and fails on the camera).
  const auto wide = evarnode(args("16384", "4096"));
  EXPECT_EQ(wide.code, 1) << wide.err;
}

// A session in video-out form (issue 31: the frames are the C-arm monitor's picture, the
// detector image enlarged 1.25 times, turned 270° and mirrored, text burned in beside it)
// gives `eval` the same ostium errors as its detector form, within 0.2 mm; so does the live
// node replaying it (`run --replay`), whose frames keep their video size.
TEST_F(Cli, AVideoOutSessionEvaluatesAsItsDetectorForm) {
  const auto out = scratch("video_out");
  write_text(out / "monitor.json", R"({"format": "evarnode-video-mapping", "version": 1, "video_size_px": [640, 512],
      "image_rect_px": [100, 8, 480, 480], "mirror": true, "rotation_deg": 270,
      "text_regions_px": [[4, 4, 90, 20], [4, 30, 90, 20], [584, 4, 52, 20], [584, 30, 52, 20]]})");
  const std::vector<std::string> sim{"sim", "session", "--seed", "1", "--detector-px", "384", "--fluoro-seconds", "1",
                                     "--no-progress"};
  auto with = [](std::vector<std::string> a, std::initializer_list<std::string> more) {
    a.insert(a.end(), more);
    return a;
  };
  ASSERT_EQ(evarnode(with(sim, {"--out", (out / "detector").string()})).code, 0);
  const auto made = evarnode(with(sim, {"--out", (out / "video").string(), "--video-out", (out / "monitor.json").string()}));
  ASSERT_EQ(made.code, 0) << made.err;
  EXPECT_NE(made.err.find("frames are the monitor's picture: 640 x 512"), std::string::npos) << made.err;
  for (const char* form : {"detector", "video"})
    ASSERT_EQ(evarnode({"eval", (out / form).string(), "--out", (out / (std::string("e-") + form)).string(), "--no-progress"}).code, 0)
        << form;
  const auto landmarks = [&](const fs::path& eval_json) {
    std::map<std::string, std::pair<double, double>> by_label;  // initial, adapted
    const auto j = nlohmann::json::parse(std::ifstream(eval_json));
    for (const auto& l : j["cases"][0]["landmarks"]) by_label[l["label"]] = {l["initial_mm"], l["adapted_mm"]};
    return by_label;
  };
  const auto detector = landmarks(out / "e-detector" / "eval.json");
  const auto video = landmarks(out / "e-video" / "eval.json");
  ASSERT_EQ(detector.size(), 4u) << std::ifstream(out / "e-detector" / "eval.json").rdbuf();
  ASSERT_EQ(video.size(), detector.size());
  for (const auto& [label, errors] : detector) {
    ASSERT_TRUE(video.count(label)) << label;
    EXPECT_NEAR(video.at(label).first, errors.first, 0.2) << label;
    EXPECT_NEAR(video.at(label).second, errors.second, 0.2) << label;
  }

  // The node on the monitor's picture adapts as eval does on the detector's frames. Without
  // the pelvis: the node registers it in the frames it happened to analyse, eval in the first
  // of each view, and half a millimetre of pose apart the models bend differently.
  ASSERT_EQ(evarnode({"eval", (out / "detector").string(), "--out", (out / "e-plain").string(), "--no-progress", "--no-pelvis"}).code, 0);
  const auto plain = landmarks(out / "e-plain" / "eval.json");
  const auto run = evarnode({"run", "--replay", (out / "video").string(), "--fast", "--no-video", "--no-igtl", "--out",
                             (out / "run").string(), "--no-progress", "--no-pelvis"});
  ASSERT_EQ(run.code, 0) << run.err;
  const auto report = nlohmann::json::parse(std::ifstream(out / "run" / "run_report.json"));
  EXPECT_EQ(report["frames"]["wrong_size"], 0) << report.dump(2);
  EXPECT_GT(report["frames"]["with_roadmap"].get<int>(), 0);
  EXPECT_FALSE(report["pelvis"]["looked_for"].get<bool>());
  for (const auto& l : report["evaluation"]["landmarks"]) {
    const std::string label = l["label"];
    ASSERT_TRUE(plain.count(label)) << label;
    EXPECT_NEAR(l["adapted_mm"].get<double>(), plain.at(label).second, 0.2) << label;
  }
}

// `calibrate-video` finds the image area of the monitor's picture within 2 px for every kind
// of display: enlarged with borders, turned and mirrored, an image intensifier's circle,
// shrunk, filling the frame; from 16-bit frames and from 8-bit display-processed ones; the
// burned-in text is boxed; the mapping goes into node.json on request, and a shape that does
// not fit the detector is said with the likely fix.
TEST_F(Cli, CalibrateVideoFindsTheImageAreaOfEveryKindOfMonitorPicture) {
  const auto out = scratch("calibrate_video");
  ASSERT_EQ(evarnode({"sim", "session", "--seed", "2", "--detector-px", "384", "--fluoro-seconds", "0.4", "--out",
                      (out / "s").string(), "--no-progress"}).code, 0);
  const auto session = evar::session::read_session(out / "s");
  std::vector<cv::Mat> detector;
  for (std::size_t i : {1u, 8u, 14u}) detector.push_back(evar::session::read_session_frame(session, i));

  struct Kind {
    const char* name;
    evar::geometry::VideoMapping m;
  };
  const auto mapping = [](int cols, int rows, evar::geometry::PixelRect r, int turn, bool mirror,
                          evar::geometry::FieldShape shape, std::vector<evar::geometry::PixelRect> text) {
    evar::geometry::VideoMapping m;
    m.video_cols = cols;
    m.video_rows = rows;
    m.image_rect = r;
    m.rotation_deg = turn;
    m.mirror = mirror;
    m.field_shape = shape;
    m.text_regions = std::move(text);
    return m;
  };
  using evar::geometry::FieldShape;
  const std::vector<Kind> kinds{
      {"enlarged, bordered, text both sides",
       mapping(1280, 1024, {128, 0, 1024, 1024}, 0, false, FieldShape::Rectangle, {{4, 10, 118, 24}, {1158, 10, 118, 24}})},
      {"turned and mirrored", mapping(640, 512, {100, 8, 480, 480}, 270, true, FieldShape::Rectangle,
                                      {{4, 4, 90, 20}, {4, 30, 90, 20}, {584, 470, 52, 20}})},
      {"image intensifier", mapping(800, 600, {137, 45, 510, 510}, 90, false, FieldShape::Circle, {{10, 560, 300, 30}})},
      {"shrunk", mapping(320, 240, {60, 21, 199, 199}, 180, false, FieldShape::Rectangle, {{2, 2, 56, 14}})},
      {"filling the frame", mapping(384, 384, {0, 0, 384, 384}, 0, false, FieldShape::Rectangle, {})},
  };
  const std::vector<std::string> text{"PATIENT DOE", "LAO 35", "FL 0012", "80 kV"};
  for (const Kind& kind : kinds) {
    for (const bool eight_bit : {false, true}) {
      SCOPED_TRACE(std::string(kind.name) + (eight_bit ? ", 8-bit display video" : ", 16-bit"));
      std::vector<std::string> args{"calibrate-video", "--out", (out / "mapping.json").string(), "--picture",
                                    (out / "found.png").string(), "--frames"};
      for (std::size_t k = 0; k < detector.size(); ++k) {
        cv::Mat picture = evar::sim::monitor_picture(detector[k], kind.m, text);
        if (eight_bit) {  // what a grabber sees: log, windowed, 8 bits, black clipped
          cv::Mat f;
          picture.convertTo(f, CV_32F);
          cv::log(f + 1.0f, f);
          f.convertTo(picture, CV_8U, 255.0 / 11.1);
        }
        const auto file = out / ("frame" + std::to_string(k) + ".png");
        ASSERT_TRUE(cv::imwrite(file.string(), picture));
        args.push_back(file.string());
      }
      const auto r = evarnode(args);
      ASSERT_EQ(r.code, 0) << r.err;
      const auto found = evar::geometry::read_video_mapping(out / "mapping.json");
      const auto& a = found.image_rect;
      const auto& b = kind.m.image_rect;
      EXPECT_NEAR(a.x, b.x, 2.0);
      EXPECT_NEAR(a.y, b.y, 2.0);
      EXPECT_NEAR(a.x + a.width, b.x + b.width, 2.0);
      EXPECT_NEAR(a.y + a.height, b.y + b.height, 2.0);
      EXPECT_EQ(found.field_shape, kind.m.field_shape);
      EXPECT_EQ(found.video_cols, kind.m.video_cols);
      // Every burned-in text pixel lies in a region found, and no region reaches into the image.
      const cv::Mat frame = cv::imread(args.back(), cv::IMREAD_UNCHANGED);
      for (const auto& t : kind.m.text_regions)
        for (int y = static_cast<int>(t.y); y < t.y + t.height; ++y)
          for (int x = static_cast<int>(t.x); x < t.x + t.width; ++x) {
            const double v = frame.depth() == CV_8U ? frame.at<std::uint8_t>(y, x) : frame.at<std::uint16_t>(y, x);
            if (v < (frame.depth() == CV_8U ? 200 : 60000)) continue;
            const bool covered = std::any_of(found.text_regions.begin(), found.text_regions.end(), [&](const auto& f) {
              return x >= f.x && x < f.x + f.width && y >= f.y && y < f.y + f.height;
            });
            ASSERT_TRUE(covered) << "text pixel " << x << ", " << y << " in no region found";
          }
      for (const auto& f : found.text_regions) {
        const bool apart = f.x + f.width <= b.x || f.x >= b.x + b.width || f.y + f.height <= b.y || f.y >= b.y + b.height;
        EXPECT_TRUE(apart) << "a text region inside the image";
      }
      EXPECT_TRUE(fs::exists(out / "found.png"));
    }
  }

  const auto with = [](std::vector<std::string> a, std::initializer_list<std::string> more) {
    a.insert(a.end(), more);
    return a;
  };
  // node.json is pointed at the mapping file, its other fields kept; a shape that does not
  // fit the detector (given, or node.json's own) leaves node.json alone and exits 1.
  write_text(out / "node.json", R"({"format": "evarnode-node", "version": 1, "min_contrast": 0})");
  const std::vector<std::string> calibrate{"calibrate-video", "--frames", (out / "frame0.png").string(), "--out",
                                           (out / "m.json").string(), "--node", (out / "node.json").string()};
  const auto misfit = evarnode(with(calibrate, {"--detector-px", "384", "300"}));
  EXPECT_EQ(misfit.code, 1) << misfit.err;
  EXPECT_NE(misfit.err.find("no turn makes it fit"), std::string::npos) << misfit.err;
  EXPECT_EQ(nlohmann::json::parse(std::ifstream(out / "node.json")).count("video_mapping"), 0u);
  EXPECT_TRUE(fs::exists(out / "m.json")) << "written for the operator to correct";

  const auto into = evarnode(with(calibrate, {"--detector-px", "384", "384"}));
  ASSERT_EQ(into.code, 0) << into.err;
  const auto node = nlohmann::json::parse(std::ifstream(out / "node.json"));
  EXPECT_EQ(node["min_contrast"], 0);
  EXPECT_EQ(node["video_mapping"], "m.json");
  const auto config = evar::app::read_node_config(out / "node.json");
  ASSERT_TRUE(config.video_mapping);
  EXPECT_EQ(config.video_mapping->image_rect.width, 384);

  write_text(out / "node.json", R"({"format": "evarnode-node", "version": 1,
      "detector": {"cols": 300, "rows": 384, "row_spacing_mm": 0.3, "col_spacing_mm": 0.3}})");
  const auto against_node = evarnode(calibrate);
  EXPECT_EQ(against_node.code, 1) << against_node.err;
  EXPECT_NE(against_node.err.find("the 300 x 384 detector"), std::string::npos) << against_node.err;
}

// A session whose last run switches to a magnified zoom mode (issue 31) evaluates as the same
// session without the switch, and the node replaying it draws the roadmap in both modes.
TEST_F(Cli, AZoomChangeSessionEvaluatesAsOneWithoutAndTheNodeFollowsTheMode) {
  const auto out = scratch("zoom");
  const std::vector<std::string> sim{"sim", "session", "--seed", "2", "--detector-px", "256", "--fluoro-seconds", "1", "--no-progress"};
  auto with = [](std::vector<std::string> a, std::initializer_list<std::string> more) {
    a.insert(a.end(), more);
    return a;
  };
  ASSERT_EQ(evarnode(with(sim, {"--out", (out / "fixed").string()})).code, 0);
  const auto made = evarnode(with(sim, {"--out", (out / "zoom").string(), "--zoom-change"}));
  ASSERT_EQ(made.code, 0) << made.err;
  EXPECT_NE(made.err.find("zoom mode 2 \"20 cm\": 256 x 256 pixels of 0.800 mm"), std::string::npos) << made.err;
  for (const char* form : {"fixed", "zoom"})
    ASSERT_EQ(evarnode({"eval", (out / form).string(), "--out", (out / (std::string("e-") + form)).string(), "--no-progress"}).code, 0)
        << form;
  const auto cases = [&](const char* form) {
    return nlohmann::json::parse(std::ifstream(out / (std::string("e-") + form) / "eval.json"))["cases"][0];
  };
  // Distances at the isocenter do not depend on the pixels they were measured in; the
  // magnified frames are other noise draws segmented on finer pixels, which moves the
  // reconstruction by hundredths of a millimetre (measured: the same figures to 0.01 mm), so
  // the video-out test's 0.2 mm bound holds with room.
  const auto fixed = cases("fixed"), zoom = cases("zoom");
  EXPECT_EQ(zoom["frames_evaluated"], fixed["frames_evaluated"]) << "frames of the magnified mode were left out";
  ASSERT_EQ(zoom["landmarks"].size(), fixed["landmarks"].size());
  for (std::size_t k = 0; k < fixed["landmarks"].size(); ++k) {
    const auto& a = fixed["landmarks"][k];
    const auto& b = zoom["landmarks"][k];
    ASSERT_EQ(a["label"], b["label"]);
    EXPECT_NEAR(b["initial_mm"].get<double>(), a["initial_mm"].get<double>(), 0.2) << a["label"];
    EXPECT_NEAR(b["adapted_mm"].get<double>(), a["adapted_mm"].get<double>(), 0.2) << a["label"];
  }
  // The node measures the ostia in every frame it shows with a model, those of the magnified
  // mode among them, as eval does (both without the pelvis: see AVideoOutSession…).
  ASSERT_EQ(evarnode({"eval", (out / "zoom").string(), "--out", (out / "e-plain").string(), "--no-progress", "--no-pelvis"}).code, 0);
  const auto plain = nlohmann::json::parse(std::ifstream(out / "e-plain" / "eval.json"))["cases"][0]["landmarks"];
  // In real time: as fast as it goes, the short session is over before the first model.
  const auto run = evarnode({"run", "--replay", (out / "zoom").string(), "--no-video", "--no-igtl", "--out",
                             (out / "run").string(), "--no-progress", "--no-pelvis"});
  ASSERT_EQ(run.code, 0) << run.err;
  const auto report = nlohmann::json::parse(std::ifstream(out / "run" / "run_report.json"));
  EXPECT_EQ(report["frames"]["wrong_size"], 0) << report.dump(2);
  EXPECT_EQ(report["frames"]["zoom_unknown"], 0) << report.dump(2);
  EXPECT_GT(report["frames"]["with_roadmap"].get<int>(), 0);
  // The node evaluates the frames it shows after its first model, eval those after its own:
  // when the model comes late (a sanitizer build) only the last view's frames, where the renal
  // ostia lie outside the magnified field, and each ostium's mean over another set of frames.
  // Replays at 8 and 12 times the pace, whose models come as late, differ from eval by up to
  // 0.19 mm; a field taken wrongly (the node not given the modes) by 13.6 mm.
  ASSERT_GE(report["evaluation"]["landmarks"].size(), 2u) << report.dump(2);
  for (const auto& l : report["evaluation"]["landmarks"])
    for (const auto& e : plain)
      if (e["label"] == l["label"]) {
        EXPECT_NEAR(l["adapted_mm"].get<double>(), e["adapted_mm"].get<double>(), 0.5) << l["label"];
      }
}
