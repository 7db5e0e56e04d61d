// 3D Slicer markups JSON: LPS/RAS handling, labels, curve and fiducial selection, writing
// files Slicer can load, and malformed files refused with the JSON path of the problem.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "evar/base/input_error.hpp"
#include "evar/geometry/markups.hpp"

namespace fs = std::filesystem;
using evar::geometry::ControlPoint;
using evar::base::InputError;
using evar::geometry::Markup;
using evar::geometry::read_curve;
using evar::geometry::read_fiducials;
using evar::geometry::read_markups;
using evar::geometry::write_markups;
using testing::HasSubstr;

namespace {

fs::path test_dir() {
  const auto* info = testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::path(testing::TempDir()) / ("evar_geometry_markups_" + std::to_string(::getpid())) /
                       (std::string(info->test_suite_name()) + "." + info->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

fs::path write_text(const fs::path& path, const std::string& text) {
  std::ofstream(path) << text;
  return path;
}

std::string markups_error(const fs::path& path) {
  try {
    read_markups(path);
  } catch (const evar::base::InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "read_markups(" << path << ") did not throw evar::base::InputError";
  return {};
}

// Shaped like a file saved by Slicer 5 (fields trimmed).
const char* kSlicerCurve = R"({
  "@schema": "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/Resources/Schema/markups-schema-v1.0.3.json#",
  "markups": [
    {
      "type": "Fiducial",
      "coordinateSystem": "LPS",
      "name": "F",
      "controlPoints": [
        {"id": "1", "label": "renal_left", "position": [1.0, 2.0, 3.0], "positionStatus": "defined"}
      ]
    },
    {
      "type": "Curve",
      "coordinateSystem": "LPS",
      "coordinateUnits": "mm",
      "locked": false,
      "name": "aorta_centerline",
      "controlPoints": [
        {"id": "1", "label": "C-1", "description": "", "associatedNodeID": "",
         "position": [10.5, -20.25, 300.0],
         "orientation": [-1.0, -0.0, -0.0, -0.0, -1.0, -0.0, 0.0, 0.0, 1.0],
         "selected": true, "locked": false, "visibility": true, "positionStatus": "defined"},
        {"id": "2", "label": "C-2", "position": [11.0, -21.0, 290.0], "positionStatus": "defined"},
        {"id": "3", "label": "C-3", "position": [0.0, 0.0, 0.0], "positionStatus": "undefined"},
        {"id": "4", "label": "C-4", "position": [12.0, -22.0, 280.0]}
      ],
      "measurements": [{"name": "length", "enabled": true, "value": 20.1, "units": "mm"}],
      "display": {"visibility": true, "opacity": 1.0, "color": [0.4, 1.0, 1.0]}
    }
  ]
})";

}  // namespace

TEST(ReadMarkups, ReadsSlicerCurveWithLabelsAndSkipsUnplacedPoints) {
  const fs::path file = write_text(test_dir() / "centerline.mrk.json", kSlicerCurve);
  const std::vector<Markup> markups = read_markups(file);
  ASSERT_EQ(markups.size(), 2u);
  EXPECT_EQ(markups[0].type, "Fiducial");
  EXPECT_EQ(markups[1].type, "Curve");
  EXPECT_EQ(markups[1].name, "aorta_centerline");
  ASSERT_EQ(markups[1].points.size(), 3u);  // the "undefined" placeholder has no position
  EXPECT_EQ(markups[1].points[0].label, "C-1");
  EXPECT_EQ(markups[1].points[0].position_lps, Eigen::Vector3d(10.5, -20.25, 300.0));
  EXPECT_EQ(markups[1].points[2].label, "C-4");
}

// Slicer 5 writes points being placed ("preview") and skipped ones ("missing", at the
// origin) too; read as points, a skipped landmark sat at (0, 0, 0) and a skipped device
// point dragged the aorta 20 mm. An unknown status is refused by field, as Slicer does.
TEST(ReadMarkups, OnlyPlacedPointsAreReadAndAnUnknownStatusIsRefused) {
  std::string text = kSlicerCurve;
  const std::string undefined = R"("positionStatus": "undefined")";
  for (const char* status : {"missing", "preview"}) {
    std::string t = text;
    t.replace(t.find(undefined), undefined.size(), std::string(R"("positionStatus": ")") + status + "\"");
    const fs::path file = write_text(test_dir() / "status.mrk.json", t);
    const auto curve = read_curve(file);
    ASSERT_EQ(curve.points.size(), 3u) << status;
    for (const auto& p : curve.points) EXPECT_NE(p.position_lps, Eigen::Vector3d::Zero()) << status;
  }
  text.replace(text.find(undefined), undefined.size(), R"("positionStatus": "bogus")");
  const fs::path file = write_text(test_dir() / "status.mrk.json", text);
  EXPECT_THAT(markups_error(file), HasSubstr("controlPoints[2].positionStatus"));
  EXPECT_THAT(markups_error(file), HasSubstr("bogus"));
}

TEST(ReadCurve, ReturnsTheFirstCurveSkippingOtherTypes) {
  const fs::path file = write_text(test_dir() / "centerline.mrk.json", kSlicerCurve);
  const Markup curve = read_curve(file);
  EXPECT_EQ(curve.name, "aorta_centerline");
  ASSERT_EQ(curve.points.size(), 3u);
  EXPECT_EQ(curve.points[2].position_lps, Eigen::Vector3d(12.0, -22.0, 280.0));
}

TEST(ReadCurve, AcceptsClosedCurve) {
  const fs::path file = write_text(
      test_dir() / "ring.mrk.json",
      R"({"markups": [{"type": "ClosedCurve", "controlPoints": [
          {"position": [0, 0, 0]}, {"position": [1, 0, 0]}, {"position": [0, 1, 0]}]}]})");
  EXPECT_EQ(read_curve(file).points.size(), 3u);
}

TEST(ReadCurve, RefusesFilesWithoutACurveOrWithTooFewPoints) {
  const fs::path dir = test_dir();
  const fs::path fiducials = write_text(
      dir / "landmarks.mrk.json",
      R"({"markups": [{"type": "Fiducial", "controlPoints": [{"position": [0, 0, 0]}]}]})");
  try {
    read_curve(fiducials);
    ADD_FAILURE() << "no throw";
  } catch (const evar::base::InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("landmarks.mrk.json: no markup of type \"Curve\""));
    EXPECT_THAT(e.what(), HasSubstr("found: Fiducial"));
  }
  const fs::path short_curve = write_text(
      dir / "short.mrk.json",
      R"({"markups": [{"type": "Curve", "name": "iliac", "controlPoints": [{"position": [0, 0, 0]}]}]})");
  try {
    read_curve(short_curve, 2);
    ADD_FAILURE() << "no throw";
  } catch (const evar::base::InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("short.mrk.json: markups[0].controlPoints: Curve 'iliac' has 1 "
                                    "control points; at least 2 are needed"));
  }
}

TEST(ReadMarkups, ConvertsRasToLpsByNegatingXAndY) {
  const fs::path file = write_text(
      test_dir() / "ras.mrk.json",
      R"({"markups": [{"type": "Curve", "coordinateSystem": "RAS", "controlPoints": [
          {"label": "a", "position": [10.0, -20.0, 30.0]}, {"label": "b", "position": [-1.5, 2.5, -3.5]}]}]})");
  const Markup curve = read_curve(file);
  ASSERT_EQ(curve.points.size(), 2u);
  EXPECT_EQ(curve.points[0].position_lps, Eigen::Vector3d(-10.0, 20.0, 30.0));
  EXPECT_EQ(curve.points[1].position_lps, Eigen::Vector3d(1.5, -2.5, -3.5));
  EXPECT_EQ(curve.points[1].label, "b");
}

TEST(ReadMarkups, MissingCoordinateSystemMeansLps) {
  const fs::path file = write_text(
      test_dir() / "plain.mrk.json",
      R"({"markups": [{"type": "Curve", "controlPoints": [{"position": [10.0, -20.0, 30.0]}]}]})");
  EXPECT_EQ(read_markups(file)[0].points[0].position_lps, Eigen::Vector3d(10.0, -20.0, 30.0));
}

TEST(ReadMarkups, NullNameAndLabelReadAsEmpty) {
  const fs::path file = write_text(
      test_dir() / "nulls.mrk.json",
      R"({"markups": [{"type": "Fiducial", "name": null, "controlPoints": [{"label": null, "position": [1, 2, 3]}]}]})");
  const std::vector<Markup> markups = read_markups(file);
  EXPECT_EQ(markups[0].name, "");
  EXPECT_EQ(markups[0].points[0].label, "");
  EXPECT_EQ(markups[0].points[0].position_lps, Eigen::Vector3d(1, 2, 3));
}

TEST(ReadMarkups, TopLevelCoordinateSystemIsTheFallback) {
  const fs::path file = write_text(
      test_dir() / "toplevel.mrk.json",
      R"({"coordinateSystem": "RAS", "markups": [{"type": "Curve", "controlPoints": [{"position": [1, 2, 3]}]}]})");
  EXPECT_EQ(read_markups(file)[0].points[0].position_lps, Eigen::Vector3d(-1, -2, 3));
}

TEST(ReadFiducials, CollectsAllFiducialPointsWithLabels) {
  const fs::path file = write_text(
      test_dir() / "landmarks.mrk.json",
      R"({"markups": [
          {"type": "Fiducial", "coordinateSystem": "RAS", "controlPoints": [
            {"label": "renal_left", "position": [1, 2, 3]}, {"label": "renal_right", "position": [4, 5, 6]}]},
          {"type": "Curve", "controlPoints": [{"label": "not a landmark", "position": [0, 0, 0]}]},
          {"type": "Fiducial", "controlPoints": [{"label": "bifurcation", "position": [7, 8, 9]}]}]})");
  const std::vector<ControlPoint> points = read_fiducials(file);
  ASSERT_EQ(points.size(), 3u);
  EXPECT_EQ(points[0].label, "renal_left");
  EXPECT_EQ(points[0].position_lps, Eigen::Vector3d(-1, -2, 3));
  EXPECT_EQ(points[1].label, "renal_right");
  EXPECT_EQ(points[2].label, "bifurcation");
  EXPECT_EQ(points[2].position_lps, Eigen::Vector3d(7, 8, 9));
}

TEST(WriteMarkups, RoundTripsExactlyAndWritesSlicerFields) {
  const fs::path file = test_dir() / "out.mrk.json";
  Markup curve{"Curve", "device", {{"D-1", {0.1, -0.2, 1.0 / 3.0}}, {"D-2", {1e-9, 12345.6789, -7.0}}}};
  Markup landmarks{"Fiducial", "landmarks", {{"renal_left", {1, 2, 3}}}};
  write_markups(file, {curve, landmarks});

  const std::vector<Markup> back = read_markups(file);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].type, "Curve");
  EXPECT_EQ(back[0].name, "device");
  ASSERT_EQ(back[0].points.size(), 2u);
  EXPECT_EQ(back[0].points[0].label, "D-1");
  EXPECT_EQ(back[0].points[0].position_lps, curve.points[0].position_lps);
  EXPECT_EQ(back[0].points[1].position_lps, curve.points[1].position_lps);
  EXPECT_EQ(back[1].points[0].label, "renal_left");

  std::ifstream in(file);
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["@schema"],
            "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/"
            "Resources/Schema/markups-schema-v1.0.3.json#");
  const auto& m = j["markups"][0];
  EXPECT_EQ(m["coordinateSystem"], "LPS");
  EXPECT_EQ(m["coordinateUnits"], "mm");
  const auto& cp = m["controlPoints"][1];
  EXPECT_EQ(cp["id"], "2");
  EXPECT_EQ(cp["label"], "D-2");
  EXPECT_EQ(cp["orientation"], nlohmann::json({1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0}));
  EXPECT_EQ(cp["positionStatus"], "defined");
  EXPECT_EQ(cp["selected"], true);
  EXPECT_EQ(cp["locked"], false);
  EXPECT_EQ(cp["visibility"], true);
}

TEST(WriteMarkups, RefusesNonFinitePoints) {
  Markup curve{"Curve", "c", {{"a", {0, std::numeric_limits<double>::quiet_NaN(), 0}}}};
  EXPECT_THROW(write_markups(test_dir() / "nan.mrk.json", {curve}), std::invalid_argument);
}

TEST(ReadMarkups, MalformedFilesNameTheFileAndTheJsonPath) {
  const fs::path dir = test_dir();
  struct Case {
    std::string name, content, expected;
  };
  const std::vector<Case> cases = {
      {"syntax.mrk.json", R"({"markups": [ {"type": "Curve",, } ]})", "invalid JSON: parse error at line 1"},
      {"empty.mrk.json", "", "invalid JSON"},
      {"far.mrk.json", R"({"markups": [{"type": "Curve", "controlPoints": [{"position": [0, 1e6, 0]}]}]})",
       "markups[0].controlPoints[0].position[1]: implausibly far from the origin"},
      {"overflow.mrk.json", R"({"markups": [{"type": "Curve", "controlPoints": [{"position": [1e999, 0, 0]}]}]})",
       "invalid JSON"},
      {"array.mrk.json", "[1, 2]", "top level: expected a JSON object, found array"},
      {"nomarkups.mrk.json", R"({"@schema": "x"})", "markups: missing"},
      {"markups_type.mrk.json", R"({"markups": {"type": "Curve"}})", "markups: expected an array, found object"},
      {"notype.mrk.json", R"({"markups": [{"name": "x"}]})", "markups[0].type: missing"},
      {"type_number.mrk.json", R"({"markups": [{"type": 3}]})", "markups[0].type: expected a string, found number"},
      {"cs.mrk.json", R"({"markups": [{"type": "Curve", "coordinateSystem": "XYZ"}]})",
       "markups[0].coordinateSystem: unknown coordinate system 'XYZ'"},
      {"units.mrk.json", R"({"markups": [{"type": "Curve", "coordinateUnits": "um"}]})",
       "markups[0].coordinateUnits: unsupported unit 'um'"},
      {"points.mrk.json", R"({"markups": [{"type": "Curve", "controlPoints": {"a": 1}}]})",
       "markups[0].controlPoints: expected an array, found object"},
      {"noposition.mrk.json",
       R"({"markups": [{"type": "Curve", "controlPoints": [{"position": [0,0,0]}, {"label": "x"}]}]})",
       "markups[0].controlPoints[1].position: missing"},
      {"two.mrk.json",
       R"({"markups": [{"type": "Curve", "controlPoints": [{"position": [0,0,0]}, {"position": [1, 2]}]}]})",
       "markups[0].controlPoints[1].position: expected an array of 3 numbers, found an array of 2 items"},
      {"string.mrk.json",
       R"({"markups": [{"type": "Curve", "controlPoints": [{"position": [0, "1", 0]}]}]})",
       "markups[0].controlPoints[0].position[1]: expected a number, found string"},
      {"label.mrk.json",
       R"({"markups": [{"type": "Curve", "controlPoints": [{"label": 5, "position": [0, 1, 0]}]}]})",
       "markups[0].controlPoints[0].label: expected a string, found number"},
      {"null.mrk.json", R"({"markups": [null]})", "markups[0]: expected an object, found null"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    write_text(dir / c.name, c.content);
    const std::string msg = markups_error(dir / c.name);
    EXPECT_THAT(msg, HasSubstr(c.name + ": "));
    EXPECT_THAT(msg, HasSubstr(c.expected));
  }
  EXPECT_THAT(markups_error(dir / "missing.mrk.json"), HasSubstr("missing.mrk.json: file does not exist"));
}
