// Patient axes codes: what each file axis points to, and the codes refused.
#include <gtest/gtest.h>

#include "evar/base/input_error.hpp"
#include "evar/prepare/patient_axes.hpp"
#include "support/error_message.hpp"

using namespace evar;

TEST(PatientAxes, CodesMapFileAxesToLps) {
  EXPECT_TRUE(prepare::parse_patient_axes("LPS").to_lps.isIdentity());
  const auto ras = prepare::parse_patient_axes("ras");
  EXPECT_EQ(ras.code, "RAS");
  EXPECT_EQ(ras.to_lps * Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(-1, -2, 3));
  // A surface in image axes whose y runs to the head and x to the patient's right.
  const auto rsp = prepare::parse_patient_axes("RSP");
  EXPECT_EQ(rsp.to_lps * Eigen::Vector3d(0, 1, 0), Eigen::Vector3d(0, 0, 1));   // y -> superior
  EXPECT_EQ(rsp.to_lps * Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(-1, 0, 0));  // x -> right
  EXPECT_EQ(rsp.to_lps * Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 1, 0));   // z -> posterior
  EXPECT_EQ(prepare::file_axis_name({0.1, -0.9, 0.2}), "-y");
  EXPECT_EQ(prepare::file_axis_name({0.0, 0.3, 0.8}), "+z");
}

TEST(PatientAxes, BadCodesAreRefusedSayingWhatACodeIs) {
  const auto error = [](const char* code) { return test::error_message<base::InputError>([&] { prepare::parse_patient_axes(code); }); };
  EXPECT_NE(error("LP").find("--axes: 'LP' is not three letters"), std::string::npos) << error("LP");
  EXPECT_NE(error("LLS").find("names the same patient axis twice"), std::string::npos);
  EXPECT_NE(error("LPX").find("has 'X', which is no patient direction"), std::string::npos);
  // Left-handed: left and right would swap.
  EXPECT_NE(error("LPI").find("mirrors the patient"), std::string::npos) << error("LPI");
  EXPECT_NE(error("RPS").find("mirrors the patient"), std::string::npos);
  EXPECT_NE(error("LP").find("one of L/R, one of P/A and one of S/I"), std::string::npos);
}
