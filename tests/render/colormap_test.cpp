// The diverging colour map and the symmetric limits: against ColorBrewer's RdBu points and hand-worked values.
#include "render/colormap.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

using namespace vmsim::render;

TEST(Colormap, EndsAndCentre) {
  const Rgb lo = diverging_colour(-1), mid = diverging_colour(0), hi = diverging_colour(1);
  EXPECT_NEAR(lo[0] * 255, 0x05, 1e-9);  // #053061, dark blue: overcut
  EXPECT_NEAR(lo[2] * 255, 0x61, 1e-9);
  EXPECT_NEAR(mid[0] * 255, 0xf7, 1e-9);  // #f7f7f7, white
  EXPECT_NEAR(hi[0] * 255, 0x67, 1e-9);   // #67001f, dark red: undercut
  EXPECT_NEAR(hi[2] * 255, 0x1f, 1e-9);
  // Clamped beyond the ends; NaN maps to the centre.
  EXPECT_EQ(diverging_colour(-7), lo);
  EXPECT_EQ(diverging_colour(3), hi);
  EXPECT_EQ(diverging_colour(NAN), mid);
  // Linear between the points: halfway between #f7f7f7 (t = 0) and #fddbc7 (t = 0.2).
  EXPECT_NEAR(diverging_colour(0.1)[1] * 255, (0xf7 + 0xdb) / 2.0, 1e-9);
  // Blue side blue, red side red.
  for (double t = 0.1; t <= 1.0; t += 0.1) {
    EXPECT_GT(diverging_colour(-t)[2], diverging_colour(-t)[0]);
    EXPECT_GT(diverging_colour(t)[0], diverging_colour(t)[2]);
  }
}

TEST(Colormap, TableColourIsTheEntryTheValueFallsIn) {
  // 256 entries over [-10, 10]: entry 128 covers [0, 0.078125).
  EXPECT_EQ(table_colour(0.01, 10), diverging_colour(-1 + 257.0 / 256));
  EXPECT_EQ(table_colour(-10, 10), diverging_colour(-1 + 1.0 / 256));
  EXPECT_EQ(table_colour(10, 10), diverging_colour(1 - 1.0 / 256));
  EXPECT_EQ(table_colour(25, 10), table_colour(10, 10));
}

TEST(Colormap, NiceLimits) {
  EXPECT_DOUBLE_EQ(nice_ceil(18.87), 20);
  EXPECT_DOUBLE_EQ(nice_ceil(20), 20);
  EXPECT_DOUBLE_EQ(nice_ceil(2.1), 2.5);
  EXPECT_DOUBLE_EQ(nice_ceil(0.003), 0.005);
  EXPECT_DOUBLE_EQ(nice_ceil(7), 10);
  const std::vector<double> v = {0.5, -18.87, NAN, 3};
  EXPECT_DOUBLE_EQ(symmetric_limit(v, 1.0), 20);
  const std::vector<double> z = {0, 0.2, -0.1};
  EXPECT_DOUBLE_EQ(symmetric_limit(z, 1.0), 1);  // the floor
}
