// V4L2 formats by name, and one filled buffer to a Frame: padding stripped, luma taken from
// YUYV, MJPEG decoded, short or garbage buffers refused by what is wrong.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "support/v4l2_test_pattern.hpp"
#include "v4l2_buffer_conversion.hpp"

namespace evar::acquisition {
namespace {

using test::mismatches;
using test::payload_for;

TEST(V4l2Formats, FourccNamesRoundTripAndUnknownNamesAreRefused) {
  EXPECT_EQ(fourcc_to_string(V4L2_PIX_FMT_YUYV), "YUYV");
  EXPECT_EQ(fourcc_to_string(V4L2_PIX_FMT_Y16), "Y16 ");
  EXPECT_EQ(fourcc_from_string("mjpeg"), V4L2_PIX_FMT_MJPEG);
  EXPECT_EQ(fourcc_from_string("Y16"), V4L2_PIX_FMT_Y16);
  EXPECT_FALSE(fourcc_from_string("RGB3"));
  EXPECT_FALSE(is_readable_v4l2_format(V4L2_PIX_FMT_RGB24));
}

TEST(V4l2Formats, PaddedLinesAreStrippedAndLumaIsTakenFromYuyv) {
  for (std::uint32_t fourcc : {V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_Y16, V4L2_PIX_FMT_YUYV}) {
    v4l2_pix_format fmt{};
    fmt.pixelformat = fourcc;
    fmt.width = 10;
    fmt.height = 6;
    fmt.bytesperline = (fourcc == V4L2_PIX_FMT_GREY ? 10 : 20) + 12;
    fmt.sizeimage = fmt.bytesperline * fmt.height;
    const auto data = payload_for(fmt, 3);
    Frame f;
    const V4l2Layout layout{fourcc, 10, 6, static_cast<int>(fmt.bytesperline), fmt.sizeimage};
    ASSERT_FALSE(convert_v4l2_buffer(layout, data, f)) << fourcc_to_string(fourcc);
    EXPECT_EQ(f.format, fourcc == V4L2_PIX_FMT_Y16 ? PixelFormat::Mono16 : PixelFormat::Mono8);
    EXPECT_EQ(f.stride_bytes, 10 * bytes_per_pixel(f.format));
    EXPECT_EQ(mismatches(f, 3), 0) << fourcc_to_string(fourcc);
  }
}

TEST(V4l2Formats, AShortBufferIsRefusedNamingTheSizes) {
  const V4l2Layout layout{V4L2_PIX_FMT_Y16, 640, 480, 1280, 1280 * 480};
  std::vector<std::uint8_t> data(1000);
  Frame f;
  const auto error = convert_v4l2_buffer(layout, data, f);
  ASSERT_TRUE(error);
  EXPECT_NE(error->find("holds 1000 bytes, needs 614400"), std::string::npos) << *error;
}

TEST(V4l2Formats, MjpegDecodesToTheImageWithinJpegLoss) {
  cv::Mat img(48, 64, CV_8UC1);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) img.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(40 + 2 * x + y);
  std::vector<std::uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", img, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95}));
  Frame f;
  ASSERT_FALSE(convert_v4l2_buffer({V4L2_PIX_FMT_MJPEG, 64, 48, 0, 64 * 48}, jpeg, f));
  ASSERT_EQ(f.width, 64);
  ASSERT_EQ(f.pixels.size(), 64u * 48u);
  double sum = 0;
  int worst = 0;
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) {
      const int d = std::abs(int(f.pixels[static_cast<std::size_t>(y * 64 + x)]) - img.at<std::uint8_t>(y, x));
      sum += d;
      worst = std::max(worst, d);
    }
  // A smooth ramp at quality 95 loses about a grey level on average.
  EXPECT_LT(sum / (64 * 48), 1.5);
  EXPECT_LE(worst, 8);
}

TEST(V4l2Formats, MjpegWithoutHuffmanTablesDecodesAsWithThem) {
  // Many UVC grabbers send Motion-JPEG without DHT segments, relying on the standard tables
  // of JPEG Annex K.3 (the decoder must supply them). Same frame, tables stripped.
  cv::Mat img(48, 64, CV_8UC1);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) img.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(40 + 2 * x + y);
  std::vector<std::uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", img, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95}));  // standard tables
  std::vector<std::uint8_t> stripped(jpeg.begin(), jpeg.begin() + 2);
  int tables = 0;
  for (std::size_t at = 2; at + 4 <= jpeg.size();) {
    ASSERT_EQ(jpeg[at], 0xFF) << "byte " << at;
    const int marker = jpeg[at + 1];
    if (marker == 0xDA) {  // start of scan: the entropy-coded data runs to the end
      stripped.insert(stripped.end(), jpeg.begin() + static_cast<long>(at), jpeg.end());
      break;
    }
    const std::size_t length = (std::size_t{jpeg[at + 2]} << 8) | jpeg[at + 3];
    if (marker == 0xC4) ++tables;
    else stripped.insert(stripped.end(), jpeg.begin() + static_cast<long>(at), jpeg.begin() + static_cast<long>(at + 2 + length));
    at += 2 + length;
  }
  ASSERT_GE(tables, 1);
  Frame with, without;
  ASSERT_FALSE(convert_v4l2_buffer({V4L2_PIX_FMT_MJPEG, 64, 48, 0, 64 * 48}, jpeg, with));
  const auto error = convert_v4l2_buffer({V4L2_PIX_FMT_MJPEG, 64, 48, 0, 64 * 48}, stripped, without);
  ASSERT_FALSE(error) << *error;
  EXPECT_EQ(without.pixels, with.pixels);
}

TEST(V4l2Formats, GarbageOrTheWrongSizeOfMjpegIsAnErrorNotACrash) {
  Frame f;
  std::vector<std::uint8_t> garbage(5000);
  for (std::size_t i = 0; i < garbage.size(); ++i) garbage[i] = static_cast<std::uint8_t>(i * 131 + 7);
  EXPECT_TRUE(convert_v4l2_buffer({V4L2_PIX_FMT_MJPEG, 64, 48, 0, 5000}, garbage, f));
  garbage[0] = 0xFF;
  garbage[1] = 0xD8;  // a JPEG start followed by nonsense
  EXPECT_TRUE(convert_v4l2_buffer({V4L2_PIX_FMT_MJPEG, 64, 48, 0, 5000}, garbage, f));
  cv::Mat img(20, 30, CV_8UC1, cv::Scalar(100));
  std::vector<std::uint8_t> jpeg;
  cv::imencode(".jpg", img, jpeg);
  const auto e = convert_v4l2_buffer({V4L2_PIX_FMT_MJPEG, 64, 48, 0, 5000}, jpeg, f);
  ASSERT_TRUE(e);
  EXPECT_NE(e->find("decodes to 30x20"), std::string::npos) << *e;
}

}  // namespace
}  // namespace evar::acquisition
