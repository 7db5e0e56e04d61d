#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "evar/acquisition/frame.hpp"

using namespace evar::acquisition;

TEST(PixelFormat, TwelveAndSixteenBitFramesUseTwoBytesPerPixel) {
  EXPECT_EQ(bytes_per_pixel(PixelFormat::Mono8), 1);
  EXPECT_EQ(bytes_per_pixel(PixelFormat::Mono12), 2);
  EXPECT_EQ(bytes_per_pixel(PixelFormat::Mono16), 2);
  EXPECT_EQ(std::string(to_string(PixelFormat::Mono12)), "Mono12");
}

namespace {

Frame mono16(int width, int height, int stride_bytes, std::size_t bytes) {
  Frame f;
  f.format = PixelFormat::Mono16;
  f.width = width;
  f.height = height;
  f.stride_bytes = stride_bytes;
  f.pixels.assign(bytes, 0);
  return f;
}

std::string refusal(const Frame& f) {
  try {
    check_layout(f);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "accepted";
}

}  // namespace

// What reads a frame's rows (the compositor, the segmentation, the recorder) relies on
// this: a frame whose buffer cannot hold its declared rows is refused by name, never read.
TEST(FrameLayout, AFrameIsReadableOnlyWhenItsBufferHoldsEveryRow) {
  EXPECT_EQ("accepted", refusal(mono16(4, 3, 8, 24)));
  EXPECT_EQ("accepted", refusal(mono16(4, 3, 10, 28)));  // padded rows; the last needs only its pixels
  EXPECT_EQ(refusal(mono16(4, 3, 10, 27)), "frame of 4 x 3 Mono16 holds 27 bytes, not 28");
  EXPECT_EQ(refusal(mono16(4, 3, 7, 24)),
            "frame stride 7 bytes is shorter than a row of 4 Mono16 pixels");
  EXPECT_EQ(refusal(mono16(4, 3, -8, 24)),
            "frame stride -8 bytes is shorter than a row of 4 Mono16 pixels");
  EXPECT_EQ(refusal(mono16(0, 3, 8, 24)), "frame size 0 x 3");
  EXPECT_EQ(refusal(mono16(4, 3, 8, 0)), "frame of 4 x 3 Mono16 holds 0 bytes, not 24");
  Frame mono8 = mono16(4, 3, 4, 12);
  mono8.format = PixelFormat::Mono8;
  EXPECT_EQ("accepted", refusal(mono8));
}
