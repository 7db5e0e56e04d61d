#include <gtest/gtest.h>

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcrleerg.h>
#include <dcmtk/dcmjpeg/djencode.h>
#include <dcmtk/dcmjpeg/djrplol.h>
#include <dcmtk/dcmjpls/djencode.h>

#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "evar/base/input_error.hpp"
#include "evar/geometry/xa_dicom.hpp"
#include "support/temp_dir.hpp"
#include "support/error_message.hpp"

using namespace evar::geometry;
namespace fs = std::filesystem;

namespace {

CArmView view() {
  CArmView v;
  v.primary_angle_deg = -33.25;
  v.secondary_angle_deg = 17.5;
  v.source_to_detector_mm = 1195.5;
  v.source_to_isocenter_mm = 785.0;
  v.detector_cols = 96;
  v.detector_rows = 64;
  v.row_spacing_mm = 0.308;
  v.col_spacing_mm = 0.154;
  return v;
}

cv::Mat ramp16(int seed) {
  cv::Mat m(64, 96, CV_16UC1);
  for (int i = 0; i < m.rows; ++i)
    for (int j = 0; j < m.cols; ++j) m.at<std::uint16_t>(i, j) = static_cast<std::uint16_t>((i * 61 + j * 7 + seed) % 4096);
  return m;
}

using evar::test::TempDir;

std::string error_of(const fs::path& p, int frame = 0) {
  return evar::test::error_message([&] { read_xa_dicom(p, frame); });
}

// Loads a file, lets `edit` change its dataset, saves it in `xfer`.
template <class Edit>
void rewrite(const fs::path& p, Edit edit, E_TransferSyntax xfer = EXS_LittleEndianExplicit) {
  DcmFileFormat f;
  ASSERT_TRUE(f.loadFile(OFFilename(p.c_str())).good());
  ASSERT_TRUE(f.loadAllDataIntoMemory().good());  // it is saved over the file it came from
  edit(*f.getDataset());
  ASSERT_TRUE(f.getDataset()->chooseRepresentation(xfer, nullptr).good());
  ASSERT_TRUE(f.saveFile(OFFilename(p.c_str()), xfer).good());
}

}  // namespace

TEST(XaDicom, ClassicXaRoundTripsGeometryAndEveryFrame) {
  TempDir dir;
  const fs::path p = dir.path / "run.dcm";
  write_xa_dicom(p, view(), {ramp16(0), ramp16(5), ramp16(9)}, false, 12);
  const XaFrame f = read_xa_dicom(p, 1);
  EXPECT_FALSE(f.enhanced);
  EXPECT_EQ(f.number_of_frames, 3);
  EXPECT_EQ(f.bits_stored, 12);
  EXPECT_EQ(f.view.primary_angle_deg, -33.25);
  EXPECT_EQ(f.view.secondary_angle_deg, 17.5);
  EXPECT_EQ(f.view.source_to_detector_mm, 1195.5);
  EXPECT_EQ(f.view.source_to_isocenter_mm, 785.0);
  EXPECT_EQ(f.view.row_spacing_mm, 0.308);
  EXPECT_EQ(f.view.col_spacing_mm, 0.154);
  EXPECT_EQ(f.view.detector_cols, 96);
  EXPECT_EQ(f.view.detector_rows, 64);
  ASSERT_EQ(f.pixels.type(), CV_16UC1);
  EXPECT_EQ(cv::norm(f.pixels, ramp16(5), cv::NORM_INF), 0.0);
}

TEST(XaDicom, EnhancedXaKeepsGeometryInTheFunctionalGroups) {
  TempDir dir;
  const fs::path p = dir.path / "enhanced.dcm";
  cv::Mat img(64, 96, CV_8UC1);
  cv::randu(img, 0, 255);
  write_xa_dicom(p, view(), {img}, true);
  const XaFrame f = read_xa_dicom(p);
  EXPECT_TRUE(f.enhanced);
  EXPECT_EQ(f.view.primary_angle_deg, -33.25);
  EXPECT_EQ(f.view.source_to_isocenter_mm, 785.0);  // FL in the X-Ray Geometry Sequence
  EXPECT_EQ(f.view.col_spacing_mm, 0.154);
  EXPECT_EQ(cv::norm(f.pixels, img, cv::NORM_INF), 0.0);
  // And the same projection as the view it was written from.
  const auto P = projection_matrix(f.view), Q = projection_matrix(view());
  EXPECT_LT((*project(P, {20, -10, 35}) - *project(Q, {20, -10, 35})).norm(), 1e-9);
}

TEST(XaDicom, PerFrameGeometryWinsOverShared) {
  TempDir dir;
  const fs::path p = dir.path / "perframe.dcm";
  write_xa_dicom(p, view(), {ramp16(1), ramp16(2)}, true);
  rewrite(p, [](DcmDataset& ds) {
    for (long k = 0; k < 2; ++k) {
      DcmItem* frame = nullptr;
      ASSERT_TRUE(ds.findOrCreateSequenceItem(DCM_PerFrameFunctionalGroupsSequence, frame, k).good());
      DcmItem* pos = nullptr;
      ASSERT_TRUE(frame->findOrCreateSequenceItem(DCM_PositionerPositionSequence, pos, 0).good());
      pos->putAndInsertString(DCM_PositionerPrimaryAngle, k == 0 ? "10" : "40");
      pos->putAndInsertString(DCM_PositionerSecondaryAngle, "0");
    }
  });
  EXPECT_EQ(read_xa_dicom(p, 0).view.primary_angle_deg, 10.0);
  EXPECT_EQ(read_xa_dicom(p, 1).view.primary_angle_deg, 40.0);
  EXPECT_EQ(read_xa_dicom(p, 1).view.source_to_detector_mm, 1195.5);  // still shared
}

TEST(XaDicom, CompressedPixelDataIsDecoded) {
  TempDir dir;
  DcmRLEEncoderRegistration::registerCodecs();
  DJEncoderRegistration::registerCodecs();
  DJLSEncoderRegistration::registerCodecs();
  for (const E_TransferSyntax xfer : {EXS_RLELossless, EXS_JPEGProcess14SV1, EXS_JPEGLSLossless}) {
    const fs::path p = dir.path / ("c" + std::to_string(static_cast<int>(xfer)) + ".dcm");
    write_xa_dicom(p, view(), {ramp16(3), ramp16(4)}, false, 12);
    rewrite(p, [](DcmDataset&) {}, xfer);
    const XaFrame f = read_xa_dicom(p, 1);
    EXPECT_EQ(cv::norm(f.pixels, ramp16(4), cv::NORM_INF), 0.0) << DcmXfer(xfer).getXferName();
  }
}

TEST(XaDicom, Monochrome1IsInvertedSoDarkStillMeansAttenuating) {
  TempDir dir;
  const fs::path p = dir.path / "m1.dcm";
  write_xa_dicom(p, view(), {ramp16(0)}, false, 12);
  rewrite(p, [](DcmDataset& ds) { ds.putAndInsertString(DCM_PhotometricInterpretation, "MONOCHROME1"); });
  cv::Mat expected;
  cv::subtract(cv::Scalar(4095), ramp16(0), expected, cv::noArray(), CV_16UC1);
  EXPECT_EQ(cv::norm(read_xa_dicom(p).pixels, expected, cv::NORM_INF), 0.0);
}

TEST(XaDicom, MissingOrImplausibleAttributesAreNamed) {
  TempDir dir;
  const fs::path p = dir.path / "bad.dcm";
  write_xa_dicom(p, view(), {ramp16(0)});
  rewrite(p, [](DcmDataset& ds) { delete ds.remove(DCM_DistanceSourceToDetector); });
  EXPECT_NE(error_of(p).find("DistanceSourceToDetector (0018,1110): missing"), std::string::npos) << error_of(p);
  write_xa_dicom(p, view(), {ramp16(0)});
  rewrite(p, [](DcmDataset& ds) { ds.putAndInsertString(DCM_DistanceSourceToPatient, "1300"); });
  EXPECT_NE(error_of(p).find("not less than"), std::string::npos) << error_of(p);
  write_xa_dicom(p, view(), {ramp16(0)});
  rewrite(p, [](DcmDataset& ds) { ds.putAndInsertString(DCM_PositionerSecondaryAngle, "120"); });
  EXPECT_NE(error_of(p).find("PositionerSecondaryAngle (0018,1511): 120 is implausible"), std::string::npos) << error_of(p);
  write_xa_dicom(p, view(), {ramp16(0)});
  EXPECT_NE(error_of(p, 1).find("frame 1 requested, the file has 1"), std::string::npos);
  rewrite(p, [](DcmDataset& ds) { ds.putAndInsertString(DCM_PhotometricInterpretation, "RGB"); });
  EXPECT_NE(error_of(p).find("PhotometricInterpretation"), std::string::npos) << error_of(p);
  write_xa_dicom(p, view(), {ramp16(0)});
  rewrite(p, [](DcmDataset& ds) { ds.putAndInsertString(DCM_NumberOfFrames, "2"); });  // pixels for one
  EXPECT_NE(error_of(p).find("PixelData (7FE0,0010): holds"), std::string::npos) << error_of(p);
  // Each side within 16384, but 2^27 pixels a frame: refused before the pixels are read.
  write_xa_dicom(p, view(), {ramp16(0)});
  rewrite(p, [](DcmDataset& ds) {
    ds.putAndInsertUint16(DCM_Rows, 8192);
    ds.putAndInsertUint16(DCM_Columns, 16384);
  });
  EXPECT_NE(error_of(p).find("16384 x 8192 pixels a frame; at most 67108864 in all"), std::string::npos) << error_of(p);
}

TEST(XaDicom, GarbageIsAClearErrorNotACrash) {
  TempDir dir;
  const fs::path p = dir.path / "garbage.dcm";
  std::ofstream(p) << std::string(300, 'x');
  EXPECT_NE(error_of(p).find("not a readable DICOM file"), std::string::npos) << error_of(p);
  EXPECT_NE(error_of(dir.path / "absent.dcm").find("does not exist"), std::string::npos);
  // A valid file cut short at every 97th byte: always a clear InputError.
  write_xa_dicom(p, view(), {ramp16(0)}, true);
  std::ifstream in(p, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  for (std::size_t n = 0; n < bytes.size(); n += 97) {
    std::ofstream(dir.path / "cut.dcm", std::ios::binary) << bytes.substr(0, n);
    EXPECT_THROW(read_xa_dicom(dir.path / "cut.dcm"), evar::base::InputError) << "cut at " << n;
  }
}

TEST(XaDicom, HighBitShiftsTheStoredBitsDown) {
  TempDir dir;
  const fs::path p = dir.path / "hb.dcm";
  cv::Mat shifted;
  ramp16(0).convertTo(shifted, CV_16UC1, 16.0);  // 12 significant bits stored in bits 4..15
  write_xa_dicom(p, view(), {shifted}, false, 16);
  rewrite(p, [](DcmDataset& ds) {
    ds.putAndInsertUint16(DCM_BitsStored, 12);
    ds.putAndInsertUint16(DCM_HighBit, 15);
  });
  EXPECT_EQ(cv::norm(read_xa_dicom(p).pixels, ramp16(0), cv::NORM_INF), 0.0);
  EXPECT_THROW(write_xa_dicom(p, view(), {shifted}, false, 12), std::invalid_argument);  // values above 12 bits
}

TEST(XaDicom, RotationalRunFramesAreRefusedNotMisplaced) {
  TempDir dir;
  const fs::path p = dir.path / "rot.dcm";
  write_xa_dicom(p, view(), {ramp16(0), ramp16(1)}, false, 12);
  rewrite(p, [](DcmDataset& ds) { ds.putAndInsertString(DCM_PositionerPrimaryAngleIncrement, "0\\1.5"); });
  EXPECT_NO_THROW(read_xa_dicom(p, 0));
  EXPECT_NE(error_of(p, 1).find("PositionerPrimaryAngleIncrement (0018,1520)"), std::string::npos) << error_of(p, 1);
  // Increments read as steps from the first frame put frame 2 at base + 15 + 0: refused
  // too (before the fix only its own increment, 0, was looked at).
  const fs::path three = dir.path / "rot3.dcm";
  write_xa_dicom(three, view(), {ramp16(0), ramp16(1), ramp16(2)}, false, 12);
  rewrite(three, [](DcmDataset& ds) { ds.putAndInsertString(DCM_PositionerSecondaryAngleIncrement, "0\\15\\0"); });
  EXPECT_NO_THROW(read_xa_dicom(three, 0));
  EXPECT_NE(error_of(three, 2).find("PositionerSecondaryAngleIncrement (0018,1521)"), std::string::npos) << error_of(three, 2);
  // A positioner that says it moved.
  const fs::path moving = dir.path / "dynamic.dcm";
  write_xa_dicom(moving, view(), {ramp16(0), ramp16(1)}, false, 12);
  rewrite(moving, [](DcmDataset& ds) { ds.putAndInsertString(DCM_PositionerMotion, "DYNAMIC"); });
  EXPECT_NO_THROW(read_xa_dicom(moving, 0));
  EXPECT_NE(error_of(moving, 1).find("DYNAMIC"), std::string::npos) << error_of(moving, 1);
}

// Attributes that would make the plain detector model place the roadmap wrongly (mirrored,
// turned, not a C-arm) are refused by name; before the fix they were ignored.
TEST(XaDicom, AFlippedOrTurnedFieldOfViewOrAnotherPositionerIsRefusedByName) {
  TempDir dir;
  const std::pair<DcmTagKey, const char*> cases[] = {{DCM_FieldOfViewHorizontalFlip, "YES"},
                                                     {DCM_FieldOfViewRotation, "90"},
                                                     {DCM_PositionerType, "COLUMN"}};
  for (const auto& [key, value] : cases) {
    const fs::path p = dir.path / "fov.dcm";
    write_xa_dicom(p, view(), {ramp16(0)}, false, 12);
    rewrite(p, [&](DcmDataset& ds) { ds.putAndInsertString(key, value); });
    const auto why = error_of(p);
    EXPECT_NE(why.find(DcmTag(key).getTagName()), std::string::npos) << why;
  }
  // The harmless values are read as before.
  const fs::path plain = dir.path / "plain.dcm";
  write_xa_dicom(plain, view(), {ramp16(0)}, false, 12);
  rewrite(plain, [](DcmDataset& ds) {
    ds.putAndInsertString(DCM_FieldOfViewHorizontalFlip, "NO");
    ds.putAndInsertString(DCM_FieldOfViewRotation, "0");
    ds.putAndInsertString(DCM_PositionerType, "CARM");
  });
  EXPECT_NO_THROW(read_xa_dicom(plain));
}
