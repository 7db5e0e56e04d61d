// Numbers in messages as people write them.
#include <gtest/gtest.h>

#include <cmath>

#include "evar/base/quantity_text.hpp"

using evar::base::quantity_text;

TEST(QuantityText, DropsTrailingZerosAndKeepsWhatMatters) {
  EXPECT_EQ(quantity_text(3.0, "mm"), "3 mm");
  EXPECT_EQ(quantity_text(2.5, "mm"), "2.5 mm");
  EXPECT_EQ(quantity_text(0.05, "mm"), "0.05 mm");
  EXPECT_EQ(quantity_text(1234.5678, "mm"), "1234.57 mm");
  EXPECT_EQ(quantity_text(13.04, "mm", 1), "13 mm");
  EXPECT_EQ(quantity_text(-0.001, "mm"), "0 mm");
  EXPECT_EQ(quantity_text(-4.25, ""), "-4.25");
  EXPECT_EQ(quantity_text(INFINITY, "mm"), "inf mm");
  EXPECT_EQ(quantity_text(NAN, "mm"), "nan mm");
}
