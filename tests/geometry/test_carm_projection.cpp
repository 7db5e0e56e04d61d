#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "evar/geometry/carm_projection.hpp"
#include "evar/base/input_error.hpp"

using namespace evar::geometry;
namespace fs = std::filesystem;

namespace {

CArmView view(double primary, double secondary) {
  CArmView v;
  v.primary_angle_deg = primary;
  v.secondary_angle_deg = secondary;
  v.source_to_detector_mm = 1200.0;
  v.source_to_isocenter_mm = 800.0;
  v.detector_cols = 1024;
  v.detector_rows = 768;
  v.row_spacing_mm = 0.3;
  v.col_spacing_mm = 0.4;
  return v;
}

Eigen::Vector2d px(const ProjectionMatrix& P, const Eigen::Vector3d& X) {
  const auto p = project(P, X);
  EXPECT_TRUE(p.has_value());
  return p.value_or(Eigen::Vector2d::Constant(std::nan("")));
}

fs::path temp_dir() {
  const fs::path dir = fs::temp_directory_path() / ("evar_carm_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

void write(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

}  // namespace

TEST(CArmProjection, IsocenterLandsOnTheImageCentreAtEveryAngle) {
  for (const double a : {-120.0, -45.0, 0.0, 30.0, 90.0, 180.0})
    for (const double b : {-40.0, 0.0, 25.0}) {
      const auto P = projection_matrix(view(a, b));
      const Eigen::Vector2d c = px(P, Eigen::Vector3d::Zero());
      EXPECT_NEAR(c.x(), 511.5, 1e-9) << a << "/" << b;  // (cols − 1) / 2
      EXPECT_NEAR(c.y(), 383.5, 1e-9) << a << "/" << b;
    }
}

TEST(CArmProjection, AtZeroZeroPatientLeftIsImageRightAndHeadIsUp) {
  const auto P = projection_matrix(view(0, 0));
  const Eigen::Vector2d c = px(P, Eigen::Vector3d::Zero());
  EXPECT_GT(px(P, {10, 0, 0}).x(), c.x() + 1);   // +x (Left) → +u
  EXPECT_NEAR(px(P, {10, 0, 0}).y(), c.y(), 1e-9);
  EXPECT_LT(px(P, {0, 0, 10}).y(), c.y() - 1);   // +z (Superior) → −v (up)
  EXPECT_NEAR(px(P, {0, 0, 10}).x(), c.x(), 1e-9);
  // The source is posterior (patient supine, detector above the chest).
  const auto cam = pinhole_camera(P);
  EXPECT_TRUE(cam.source_mm.isApprox(Eigen::Vector3d(0, 800, 0), 1e-12));
  EXPECT_TRUE(cam.direction.isApprox(Eigen::Vector3d(0, -1, 0), 1e-12));
}

TEST(CArmProjection, Lao90PutsTheDetectorOnThePatientsLeft) {
  const auto cam = pinhole_camera(projection_matrix(view(90, 0)));
  EXPECT_NEAR(cam.source_mm.x(), -800.0, 1e-9);  // source on the right
  EXPECT_TRUE(cam.direction.isApprox(Eigen::Vector3d(1, 0, 0), 1e-12));
  const auto rao = pinhole_camera(projection_matrix(view(-90, 0)));
  EXPECT_NEAR(rao.source_mm.x(), 800.0, 1e-9);
}

TEST(CArmProjection, CranialTiltPutsTheDetectorTowardsTheHead) {
  const auto cra = pinhole_camera(projection_matrix(view(0, 30)));
  EXPECT_GT(cra.direction.z(), 0.49);  // sin 30°
  EXPECT_LT(cra.source_mm.z(), -399.0);  // source caudal: −SOD sin 30°
  const auto cau = pinhole_camera(projection_matrix(view(0, -30)));
  EXPECT_LT(cau.direction.z(), -0.49);
}

// Both angles at once pin the order of the two turns (DICOM PS3.3 C.8.7.5: the primary
// angle turns about the long axis, the secondary tilts within the plane it reached):
// viewing direction (sin a cos b, −cos a cos b, sin b). Facts, not the code's own rotation:
// swapping the turns (Rx·Rz) leaves LAO 90 / CRA 30 with no cranial component at all.
TEST(CArmProjection, BothAnglesTogetherFollowDicomsOrderOfTurns) {
  const double c30 = std::cos(M_PI / 6), s45 = std::sqrt(0.5);
  const std::pair<std::pair<double, double>, Eigen::Vector3d> facts[] = {
      {{90, 30}, Eigen::Vector3d(c30, 0, 0.5)},
      {{45, 30}, Eigen::Vector3d(s45 * c30, -s45 * c30, 0.5)},
      {{-45, -30}, Eigen::Vector3d(-s45 * c30, -s45 * c30, -0.5)},
      {{30, -20}, Eigen::Vector3d(0.5 * std::cos(M_PI / 9), -std::cos(M_PI / 6) * std::cos(M_PI / 9), -std::sin(M_PI / 9))}};
  for (const auto& [angles, direction] : facts) {
    const auto cam = pinhole_camera(projection_matrix(view(angles.first, angles.second)));
    EXPECT_LT((cam.direction - direction).norm(), 1e-12) << angles.first << "/" << angles.second;
    EXPECT_LT((cam.source_mm + 800.0 * direction).norm(), 1e-9) << angles.first << "/" << angles.second;
  }
}

TEST(CArmProjection, MagnificationAtTheIsocenterIsSidOverSod) {
  for (const double a : {0.0, 40.0, -70.0}) {
    const auto P = projection_matrix(view(a, 10));
    const Eigen::Matrix3d M = carm_rotation(a, 10);
    const Eigen::Vector3d u = M * Eigen::Vector3d::UnitX();
    const Eigen::Vector3d v = M * Eigen::Vector3d(0, 0, -1);
    // 10 mm across the beam at the isocenter: 10 · 1200/800 mm on the detector.
    EXPECT_NEAR((px(P, 5 * u) - px(P, -5 * u)).norm(), 10 * 1.5 / 0.4, 1e-9);
    EXPECT_NEAR((px(P, 5 * v) - px(P, -5 * v)).norm(), 10 * 1.5 / 0.3, 1e-9);
    // Closer to the source magnifies more.
    const Eigen::Vector3d d = pinhole_camera(P).direction;
    EXPECT_GT((px(P, 5 * u - 100 * d) - px(P, -5 * u - 100 * d)).norm(), 10 * 1.5 / 0.4 + 1);
  }
}

TEST(CArmProjection, DepthBackProjectionAndBehindTheSource) {
  const auto P = projection_matrix(view(25, -15));
  const auto cam = pinhole_camera(P);
  EXPECT_NEAR(depth_mm(P, Eigen::Vector3d::Zero()), 800.0, 1e-9);
  const Eigen::Vector3d X(30, -20, 55);
  const Eigen::Vector3d ray = back_projected_ray(cam, px(P, X));
  EXPECT_LT((cam.source_mm + ray * (X - cam.source_mm).norm() - X).norm(), 1e-9);
  EXPECT_FALSE(project(P, cam.source_mm - 10 * cam.direction).has_value());
  EXPECT_FALSE(project(P, cam.source_mm).has_value());
}

TEST(CArmProjection, ACalibratedMatrixWinsAndIsRecoveredAsACamera) {
  CArmView calibrated = view(0, 0);
  ProjectionMatrix Q = projection_matrix(view(35, 20));
  calibrated.projection_matrix = 2.5 * Q;  // any positive scale
  const auto P = projection_matrix(calibrated);
  const Eigen::Vector3d X(12, -7, 40);
  EXPECT_LT((px(P, X) - px(Q, X)).norm(), 1e-9);
  EXPECT_TRUE(pinhole_camera(P).source_mm.isApprox(pinhole_camera(Q).source_mm, 1e-9));
  calibrated.projection_matrix = -Q;  // depth negative in front: refused, not mirrored
  EXPECT_THROW(projection_matrix(calibrated), std::invalid_argument);
}

TEST(CArmProjection, RegistrationMovesCtPointsIntoTheCArmFrame) {
  const auto P = projection_matrix(view(0, 0));
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.block<3, 1>(0, 3) = Eigen::Vector3d(-100, 20, 300);  // CT origin far from the isocenter
  EXPECT_LT((px(registered(P, T), {100, -20, -300}) - px(P, Eigen::Vector3d::Zero())).norm(), 1e-9);
}

TEST(CArmProjection, ViewGeometryFileRoundTrips) {
  const fs::path dir = temp_dir();
  CArmView v = view(-33.5, 12.25);
  write_view_geometry(dir / "a.json", v);
  const CArmView r = read_view_geometry(dir / "a.json");
  EXPECT_EQ(r.primary_angle_deg, v.primary_angle_deg);
  EXPECT_EQ(r.secondary_angle_deg, v.secondary_angle_deg);
  EXPECT_EQ(r.detector_cols, 1024);
  EXPECT_EQ(r.detector_rows, 768);
  EXPECT_EQ(r.row_spacing_mm, 0.3);
  EXPECT_EQ(r.col_spacing_mm, 0.4);
  EXPECT_FALSE(r.projection_matrix.has_value());
  v.projection_matrix = projection_matrix(view(10, 10));
  write_view_geometry(dir / "b.json", v);
  EXPECT_EQ(*read_view_geometry(dir / "b.json").projection_matrix, *v.projection_matrix);  // bit-exact
  fs::remove_all(dir);
}

TEST(CArmProjection, BadViewGeometryNamesTheField) {
  const fs::path dir = temp_dir();
  const std::string good =
      R"({"primary_angle_deg": 10, "secondary_angle_deg": 0, "source_to_detector_mm": 1200,
          "source_to_isocenter_mm": 800, "detector_size_px": [1024, 1024], "pixel_spacing_mm": [0.3, 0.3]})";
  write(dir / "good.json", good);
  EXPECT_NO_THROW(read_view_geometry(dir / "good.json"));
  const auto message = [&](std::string text) {
    write(dir / "bad.json", text);
    try {
      read_view_geometry(dir / "bad.json");
    } catch (const evar::base::InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const auto replaced = [&](const std::string& from, const std::string& to) {
    std::string t = good;
    t.replace(t.find(from), from.size(), to);
    return message(t);
  };
  EXPECT_NE(replaced("\"primary_angle_deg\": 10", "\"primary_angle_deg\": 200").find("primary_angle_deg"), std::string::npos);
  EXPECT_NE(replaced("\"source_to_isocenter_mm\": 800", "\"source_to_isocenter_mm\": 1300").find("source_to_isocenter_mm"),
            std::string::npos);
  EXPECT_NE(replaced("[1024, 1024]", "[1024.5, 1024]").find("detector_size_px[0]"), std::string::npos);
  EXPECT_NE(replaced("[0.3, 0.3]", "[0.3]").find("pixel_spacing_mm"), std::string::npos);
  EXPECT_NE(replaced("[0.3, 0.3]", "[0.3, -1]").find("column spacing"), std::string::npos);
  EXPECT_NE(replaced("\"secondary_angle_deg\": 0,", "").find("secondary_angle_deg: missing"), std::string::npos);
  EXPECT_NE(replaced("}", R"(, "projection_matrix": [[1,0,0,0],[0,1,0,0],[0,0,0,1]]})").find("singular"), std::string::npos);
  EXPECT_NE(replaced("}", R"(, "projection_matrix": [[1,0,0,0],[0,1,0,0]]})").find("projection_matrix"), std::string::npos);
  EXPECT_NE(message("{\"primary_angle_deg\": ").find("invalid JSON"), std::string::npos);
  EXPECT_NE(message("[]").find("top level"), std::string::npos);
  fs::remove_all(dir);
}

TEST(CArmProjection, RegistrationFileIsCheckedForMirrorsAndScale) {
  const fs::path dir = temp_dir();
  write(dir / "t.json", R"({"matrix": [[0,-1,0,10],[1,0,0,20],[0,0,1,30],[0,0,0,1]]})");
  const Eigen::Matrix4d T = read_registration(dir / "t.json");
  EXPECT_EQ(T(0, 3), 10);
  EXPECT_EQ(T(1, 0), 1);
  const auto error = [&](const std::string& text) {
    write(dir / "t.json", text);
    try {
      read_registration(dir / "t.json");
    } catch (const evar::base::InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error(R"({"matrix": [[-1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]})").find("mirrors"), std::string::npos);
  EXPECT_NE(error(R"({"matrix": [[10,0,0,0],[0,10,0,0],[0,0,10,0],[0,0,0,1]]})").find("rigid"), std::string::npos);
  EXPECT_NE(error(R"({"matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,1,1]]})").find("matrix[3]"), std::string::npos);
  EXPECT_NE(error(R"({"matrix": [[1,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]})").find("matrix[0]"), std::string::npos);
  fs::remove_all(dir);
}
