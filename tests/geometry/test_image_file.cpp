// Image files read once and decoded from memory: a 16-bit PNG comes back exactly, garbage
// and oversized files end in an InputError naming the file.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "evar/geometry/image_file.hpp"
#include "evar/base/input_error.hpp"
#include "support/error_message.hpp"
#include "support/temp_dir.hpp"

namespace fs = std::filesystem;
using evar::base::InputError;
using evar::geometry::read_image_file;
using testing::HasSubstr;

namespace {

std::string error_of(const fs::path& file) {
  return evar::test::error_message([&] { read_image_file(file); });
}

}  // namespace

TEST(ImageFile, ASixteenBitPngComesBackExactly) {
  evar::test::TempDir dir;
  cv::Mat img(7, 5, CV_16UC1);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) img.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(9000 * y + 31 * x + 1);
  ASSERT_TRUE(cv::imwrite((dir.path / "f.png").string(), img));
  const cv::Mat back = read_image_file(dir.path / "f.png");
  ASSERT_EQ(back.type(), CV_16UC1);
  EXPECT_EQ(cv::norm(back, img, cv::NORM_INF), 0.0);
}

TEST(ImageFile, GarbageAndOversizedFilesAreRefusedByName) {
  evar::test::TempDir dir;
  std::ofstream(dir.path / "torn.png", std::ios::binary) << "\x89PNG\r\n\x1a\n but then nothing";
  EXPECT_THAT(error_of(dir.path / "torn.png"), HasSubstr("torn.png: "));
  std::ofstream(dir.path / "huge.png") << "x";
  fs::resize_file(dir.path / "huge.png", 300ull << 20);  // sparse: no disk used
  EXPECT_THAT(error_of(dir.path / "huge.png"), HasSubstr("huge.png: is 300 MiB, more than the 256 MiB accepted for an image file"));
  EXPECT_THAT(error_of(dir.path / "absent.png"), HasSubstr("absent.png: file does not exist"));
}
