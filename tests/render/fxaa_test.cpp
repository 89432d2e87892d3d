// FXAA on the CPU (render/fxaa.hpp) against VTK's own FXAA shader (vtkOpenGLFXAAFilter on Mesa's llvmpipe, an
// independent implementation of the same algorithm: Antialiasing::FxaaVtk), and against cases worked by hand from
// the algorithm (a flat picture is unchanged; a lone bright pixel on black is blended 3/4 of the way to its 3 x 3
// mean, 1/3 -> 85; a straight vertical step edge is left alone, FXAA having no stair to smooth).
#include "render/fxaa.hpp"
#include "render/scene.hpp"
#include "render_test_support.hpp"

#include "core/error.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace vmsim;
using namespace vmsim::render;

namespace {

Image fxaatest_image(int w, int h, std::uint8_t v) {
  Image img;
  img.width = w, img.height = h;
  img.rgb.assign(static_cast<std::size_t>(w) * h * 3, v);
  return img;
}

void fxaatest_set(Image& img, int x, int y, std::uint8_t v) {
  const std::size_t o = (static_cast<std::size_t>(y) * img.width + x) * 3;
  img.rgb[o] = img.rgb[o + 1] = img.rgb[o + 2] = v;
}

// A tilted block with a bump and a groove: silhouettes, creases and raking-light streaks.
core::HeightGrid fxaatest_part() {
  core::HeightGrid g;
  g.dx_mm = g.dy_mm = 0.1;
  g.z_mm.resize(161, 241);
  for (Eigen::Index j = 0; j < g.ny(); ++j)
    for (Eigen::Index i = 0; i < g.nx(); ++i)
      g.z_mm(j, i) = 0.04 * g.x(i) + 1.2 * std::exp(-std::pow(g.x(i) - 12, 2) / 6 - std::pow(g.y(j) - 8, 2) / 4) -
                     0.3 * std::exp(-std::pow(g.y(j) - 4, 2) / 0.05) + 0.01 * std::sin(g.x(i) * 9);
  return g;
}

struct FxaaTestDiff {
  double differing = 0;  // fraction of the pixels
  int max = 0;
};

FxaaTestDiff fxaatest_diff(const Image& a, const Image& b) {
  FxaaTestDiff d;
  std::size_t n = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) {
      const int m = static_cast<int>(test::colour_distance(a.at(x, y), b.at(x, y)));
      d.max = std::max(d.max, m);
      n += m > 0;
    }
  d.differing = static_cast<double>(n) / (static_cast<double>(a.width) * a.height);
  return d;
}

}  // namespace

TEST(Fxaa, FlatPictureUnchanged) {
  Image img = fxaatest_image(40, 30, 120);
  const Image before = img;
  fxaa(img, PixelRect{0, 0, 40, 30});
  EXPECT_EQ(img.rgb, before.rgb);
}

TEST(Fxaa, LoneSpeckBlendedTowardsItsMean) {
  // A white pixel on black: contrast 1, sub-pixel blend min(3/4, (1 - 1/4) / (3/4)) = 3/4 towards the 3 x 3 mean
  // 1/9, and no edge resampling (both endpoints one step away): 1 - 3/4 * 8/9 = 1/3 -> 85.
  Image img = fxaatest_image(21, 21, 0);
  fxaatest_set(img, 10, 10, 255);
  fxaa(img, PixelRect{0, 0, 21, 21});
  EXPECT_EQ(img.at(10, 10)[0], 85);
  // Pixels two away see no contrast among their four neighbours: untouched.
  EXPECT_EQ(img.at(12, 10)[0], 0);
  EXPECT_EQ(img.at(10, 13)[0], 0);
}

TEST(Fxaa, OnlyTheRectangleChanges) {
  Image img = fxaatest_image(30, 20, 0);
  for (int y = 0; y < 20; ++y)
    for (int x = 0; x < 30; ++x)
      if ((x + y) % 2 == 0) fxaatest_set(img, x, y, 255);  // a checkerboard: every pixel a speck
  const Image before = img;
  fxaa(img, PixelRect{5, 4, 10, 8});
  for (int y = 0; y < 20; ++y)
    for (int x = 0; x < 30; ++x) {
      const bool inside = x >= 5 && x < 15 && y >= 4 && y < 12;
      if (!inside) EXPECT_EQ(img.at(x, y), before.at(x, y)) << x << "," << y;
    }
  EXPECT_NE(img.at(8, 6), before.at(8, 6));
}

TEST(Fxaa, StraightStepEdgeLeftAlone) {
  // A vertical edge along whole columns: the search runs the full length on both sides, the nearest endpoint's
  // sample stays on C's side, so no pixel is resampled; no speck either.
  Image img = fxaatest_image(24, 24, 30);
  for (int y = 0; y < 24; ++y)
    for (int x = 12; x < 24; ++x) fxaatest_set(img, x, y, 220);
  const Image before = img;
  fxaa(img, PixelRect{0, 0, 24, 24});
  EXPECT_EQ(img.rgb, before.rgb);
}

TEST(Fxaa, RectangleOutsideTheImageThrows) {
  Image img = fxaatest_image(10, 10, 0);
  EXPECT_THROW(fxaa(img, PixelRect{5, 5, 6, 2}), core::Error);
  EXPECT_THROW(fxaa(img, PixelRect{0, 0, 0, 5}), core::Error);
}

TEST(Fxaa, MatchesVtksShaderOnAPartPicture) {
  // The same 3-D view smoothed by VTK's shader and by render/fxaa: nearly every pixel the same (measured: 19 of
  // 480 000 differ, by at most 4 levels, where the float arithmetic of a threshold test rounds the other way),
  // while FXAA itself changes ~3 400 of them.
  const core::HeightGrid g = fxaatest_part();
  PartPicture pic;
  pic.width = 800, pic.height = 600;
  pic.caption = {"fxaa test"};
  pic.antialiasing = Antialiasing::None;
  const Image plain = render_part(test::shared_window(), g, nullptr, pic).image;
  pic.antialiasing = Antialiasing::FxaaVtk;
  const Image vtk = render_part(test::shared_window(), g, nullptr, pic).image;
  pic.antialiasing = Antialiasing::Fxaa;
  const Image cpu = render_part(test::shared_window(), g, nullptr, pic).image;
  const FxaaTestDiff fxaa_effect = fxaatest_diff(plain, vtk), d = fxaatest_diff(cpu, vtk);
  EXPECT_GT(fxaa_effect.differing, 0.005) << "VTK's FXAA changed almost nothing: the comparison would be empty";
  EXPECT_LT(d.differing, 0.05 * fxaa_effect.differing);
  EXPECT_LE(d.max, 16);
  test::keep_if_failed(cpu, "_cpu");
  test::keep_if_failed(vtk, "_vtk");
}
