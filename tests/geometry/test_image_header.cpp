// Image headers are read before decoding, so a small file declaring gigapixels is refused
// without the decoder allocating them; every format's size comes out as written, and
// malformed headers name the byte.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <fstream>
#include <string>
#include <tuple>
#include <vector>

#include "evar/geometry/image_file.hpp"
#include "evar/geometry/image_header.hpp"
#include "evar/base/input_error.hpp"
#include "support/error_message.hpp"
#include "support/temp_dir.hpp"

using evar::geometry::read_image_header;
using testing::HasSubstr;

namespace {

std::string encoded(const std::string& ext, const cv::Mat& image) {
  std::vector<unsigned char> bytes;
  EXPECT_TRUE(cv::imencode(ext, image, bytes));
  return {bytes.begin(), bytes.end()};
}

std::string error_of(const std::string& bytes) {
  return evar::test::error_message([&] { read_image_header(bytes, "f.img"); });
}

void put_be32(std::string& s, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) s[at + static_cast<std::size_t>(i)] = static_cast<char>((v >> (24 - 8 * i)) & 0xFF);
}

}  // namespace

TEST(ImageHeader, PngTiffAndJpegSizesAreReadAsEncoded) {
  const cv::Mat grey16(37, 53, CV_16UC1, cv::Scalar(1234)), grey8(37, 53, CV_8UC1, cv::Scalar(77));
  for (const auto& [ext, image, format] : {std::tuple{".png", grey16, "PNG"}, std::tuple{".tiff", grey16, "TIFF"},
                                           std::tuple{".jpg", grey8, "JPEG"}}) {
    const auto h = read_image_header(encoded(ext, image), "f");
    EXPECT_EQ(h.format, format);
    EXPECT_EQ(h.width, 53) << format;
    EXPECT_EQ(h.height, 37) << format;
  }
}

TEST(ImageHeader, BigEndianTiffWithShortAndLongSizes) {
  // "MM", 42, IFD at 8: two entries, ImageWidth SHORT 300, ImageLength LONG 70000.
  std::string t("MM\0*\0\0\0\x08\0\x02", 10);
  t += std::string("\x01\x00\x00\x03\x00\x00\x00\x01\x01\x2C\x00\x00", 12);
  t += std::string("\x01\x01\x00\x04\x00\x00\x00\x01\x00\x01\x11\x70", 12);
  EXPECT_THAT(error_of(t), HasSubstr("declares 300 x 70000 pixels; at most 16384 per side"));
  t[31] = 0x00;  // ImageLength 0x00001170 = 4464
  const auto h = read_image_header(t, "f");
  EXPECT_EQ(h.format, "TIFF");
  EXPECT_EQ(h.width, 300);
  EXPECT_EQ(h.height, 4464);
}

TEST(ImageHeader, ADecompressionBombIsRefusedBeforeDecoding) {
  evar::test::TempDir dir;
  std::string png = encoded(".png", cv::Mat(8, 8, CV_16UC1, cv::Scalar(0)));
  put_be32(png, 16, 100000);  // IHDR width and height: 10^10 pixels in a file of a few hundred bytes
  put_be32(png, 20, 100000);
  EXPECT_THAT(error_of(png), HasSubstr("f.img: the PNG header declares 100000 x 100000 pixels; at most 16384 per side"));
  std::ofstream(dir.path / "bomb.png", std::ios::binary) << png;
  EXPECT_THAT(evar::test::error_message([&] { evar::geometry::read_image_file(dir.path / "bomb.png"); }),
              HasSubstr("bomb.png: the PNG header declares 100000 x 100000"));
}

TEST(ImageHeader, EachSideAndThePixelsInAllAreBounded) {
  std::string png = encoded(".png", cv::Mat(8, 8, CV_16UC1, cv::Scalar(0)));
  put_be32(png, 16, 16384);  // both sides allowed, 2^28 pixels in all are not
  put_be32(png, 20, 16384);
  EXPECT_THAT(error_of(png), HasSubstr("declares 16384 x 16384 pixels; at most 16384 per side and 67108864 in all"));
  put_be32(png, 20, 4096);  // 2^26: the most in all
  const auto h = read_image_header(png, "f");
  EXPECT_EQ(h.width, 16384);
  EXPECT_EQ(h.height, 4096);
}

TEST(ImageHeader, CutShortMalformedAndOtherFormatsNameTheirProblem) {
  const std::string png = encoded(".png", cv::Mat(4, 4, CV_8UC1, cv::Scalar(0)));
  EXPECT_THAT(error_of(png.substr(0, 18)), HasSubstr("f.img: PNG header, byte 18: the file ends inside the header"));
  std::string no_ihdr = png;
  no_ihdr[12] = 'X';
  EXPECT_THAT(error_of(no_ihdr), HasSubstr("PNG header, byte 12: the first chunk is not IHDR"));
  EXPECT_THAT(error_of(std::string("II*\0\x04\0\0\0", 8)), HasSubstr("TIFF header, byte 4: the first IFD offset 4"));
  EXPECT_THAT(error_of(std::string("\xFF\xD8\xFF\xDA\0\x02", 6)), HasSubstr("JPEG header, byte 2: no start-of-frame"));
  EXPECT_THAT(error_of(std::string("\xFF\xD8\xFF\xE0\0\x01", 6)), HasSubstr("byte 4: segment length 1 is less than 2"));
  EXPECT_THAT(error_of("BM garbage"), HasSubstr("f.img: not a PNG, TIFF or JPEG image"));
  EXPECT_THAT(error_of(""), HasSubstr("not a PNG, TIFF or JPEG image"));
  EXPECT_THAT(error_of(std::string("II+\0", 4)), HasSubstr("a BigTIFF file"));
}
