// Flat deviation maps drawn as one image (PartPicture::map_as_image) against the same maps drawn as triangles, the
// way every map was drawn before: the reference is the rasteriser's own per-pixel interpolation of the deviation over
// the grid's triangles, looked up in the same table. Both pictures are drawn here from analytic fields that vary in
// x and y (so the split of each cell into two triangles matters), and compared pixel by pixel.
#include "render/colormap.hpp"
#include "render/scene.hpp"
#include "render_test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>

using namespace vmsim;
using namespace vmsim::render;
using render::test::shared_window;

namespace {

// A wavy deviation over an nx x ny grid at dx x dy mm, on a surface with a slope and a bump (the map ignores the
// heights but the iso-lines are drawn at them).
struct MapImageFields {
  core::HeightGrid surface, deviation;
};

MapImageFields map_image_fields(Eigen::Index nx, Eigen::Index ny, double dx_mm, double dy_mm) {
  MapImageFields f;
  f.surface.x0_mm = -3.0, f.surface.y0_mm = 1.5, f.surface.dx_mm = dx_mm, f.surface.dy_mm = dy_mm;
  f.surface.z_mm = core::HeightArray::Zero(ny, nx);
  f.deviation = f.surface;
  for (Eigen::Index j = 0; j < ny; ++j)
    for (Eigen::Index i = 0; i < nx; ++i) {
      const double x = f.surface.x(i), y = f.surface.y(j);
      f.surface.z_mm(j, i) = 0.02 * x - 0.5 * std::exp(-0.05 * (x * x + (y - 6) * (y - 6)));
      // Up to +-9 um: ripples of a few cells' wavelength crossing diagonally, and a tilt.
      f.deviation.z_mm(j, i) = 1e-3 * (6.0 * std::sin(1.9 * x + 0.7 * y) * std::cos(1.3 * y - 0.4 * x) + 0.25 * x);
    }
  return f;
}

// The largest channel step between neighbouring entries of the map's table: two pictures that put a pixel's value
// into neighbouring entries (a value on an entry's border, rounded differently) differ by at most this.
double largest_table_step() {
  double step = 0;
  for (int k = 0; k + 1 < kColourTableSize; ++k) {
    const Rgb a = diverging_colour(-1 + (2.0 * k + 1) / kColourTableSize);
    const Rgb b = diverging_colour(-1 + (2.0 * k + 3) / kColourTableSize);
    for (int c = 0; c < 3; ++c) step = std::max(step, std::abs(a[c] - b[c]) * 255);
  }
  return std::ceil(step) + 1;  // +1: each colour rounded to 8 bits
}

struct MapImageDifference {
  std::size_t differing = 0, pixels = 0;
  double max = 0;
};

MapImageDifference map_image_difference(const Image& a, const Image& b) {
  MapImageDifference d;
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  for (int y = 0; y < std::min(a.height, b.height); ++y)
    for (int x = 0; x < std::min(a.width, b.width); ++x) {
      const double c = test::colour_distance(a.at(x, y), b.at(x, y));
      d.pixels++;
      if (c > 0) d.differing++, d.max = std::max(d.max, c);
    }
  std::printf("image against triangles: %zu of %zu pixels differ, max %g (one table step: %g)\n", d.differing, d.pixels,
              d.max, largest_table_step());
  return d;
}

PartPicture map_picture(int width, int height) {
  PartPicture pic;
  pic.width = width, pic.height = height;
  pic.caption = {"a wavy deviation", "drawn as an image and as triangles"};
  pic.view.direction = ViewDirection::Top;
  pic.deviation = DeviationColours{};
  pic.deviation->lit = false;
  pic.deviation->limit_mm = 0.010;
  pic.deviation->isolines = 3;
  return pic;
}

}  // namespace

// The whole map, cells of ~2 px, iso-lines on: the same picture to within one table entry at a few pixels.
TEST(MapImage, WholeMapMatchesTheTriangles) {
  const MapImageFields f = map_image_fields(181, 121, 0.05, 0.05);
  PartPicture pic = map_picture(640, 480);
  const PartImage image = render_part(shared_window(), f.surface, &f.deviation, pic);
  pic.map_as_image = false;
  const PartImage triangles = render_part(shared_window(), f.surface, &f.deviation, pic);
  const MapImageDifference d = map_image_difference(image.image, triangles.image);
  // The map covers most of the picture: had the image been misplaced by a pixel, thousands of pixels would differ.
  EXPECT_LE(d.max, largest_table_step());
  EXPECT_LE(d.differing, d.pixels / 200) << d.differing << " of " << d.pixels << " pixels differ (max " << d.max << ")";
  test::keep_if_failed(image.image, "_image");
  test::keep_if_failed(triangles.image, "_triangles");
}

// A zoom on a region of a grid finer than the picture (drawn at every 4th node, the last cell shorter), with cells
// of unequal width and height: the same.
TEST(MapImage, ZoomOnAStridedGridMatchesTheTriangles) {
  const MapImageFields f = map_image_fields(1202, 601, 0.01, 0.02);
  PartPicture pic = map_picture(400, 300);
  pic.view.region = Region{1.0, 9.0, 3.0, 11.0};
  const PartImage image = render_part(shared_window(), f.surface, &f.deviation, pic);
  pic.map_as_image = false;
  const PartImage triangles = render_part(shared_window(), f.surface, &f.deviation, pic);
  const MapImageDifference d = map_image_difference(image.image, triangles.image);
  EXPECT_LE(d.max, largest_table_step());
  EXPECT_LE(d.differing, d.pixels / 200) << d.differing << " of " << d.pixels << " pixels differ (max " << d.max << ")";
  // And a whole map of it, drawn at every 4th node along x.
  pic.view.region.reset();
  pic.map_as_image = true;
  const PartImage whole_image = render_part(shared_window(), f.surface, &f.deviation, pic);
  pic.map_as_image = false;
  const PartImage whole_triangles = render_part(shared_window(), f.surface, &f.deviation, pic);
  const MapImageDifference w = map_image_difference(whole_image.image, whole_triangles.image);
  EXPECT_LE(w.max, largest_table_step());
  EXPECT_LE(w.differing, w.pixels / 200) << w.differing << " of " << w.pixels << " pixels differ (max " << w.max << ")";
}

// A grid with holes (NaN heights) or NaN deviations keeps the triangles: the two settings give the same pixels.
TEST(MapImage, HolesAndMissingDeviationsKeepTheTriangles) {
  MapImageFields f = map_image_fields(121, 81, 0.05, 0.05);
  for (Eigen::Index j = 30; j < 40; ++j)
    for (Eigen::Index i = 50; i < 65; ++i) f.surface.z_mm(j, i) = std::numeric_limits<double>::quiet_NaN();
  for (Eigen::Index j = 60; j < 64; ++j) f.deviation.z_mm(j, 10) = std::numeric_limits<double>::quiet_NaN();
  PartPicture pic = map_picture(480, 360);
  const PartImage image = render_part(shared_window(), f.surface, &f.deviation, pic);
  pic.map_as_image = false;
  const PartImage triangles = render_part(shared_window(), f.surface, &f.deviation, pic);
  EXPECT_EQ(map_image_difference(image.image, triangles.image).differing, 0u);
}

// A viewport over 4096 x 4096 pixels draws the triangles (the image would outgrow a picture's memory budget): the
// map is there, and the same as with map_as_image = false.
TEST(MapImage, HugePictureFallsBackToTheTriangles) {
  const MapImageFields f = map_image_fields(61, 41, 0.2, 0.2);
  PartPicture pic = map_picture(4700, 4700);
  pic.deviation->isolines = 0;
  const PartImage image = render_part(shared_window(), f.surface, &f.deviation, pic);
  pic.map_as_image = false;
  const PartImage triangles = render_part(shared_window(), f.surface, &f.deviation, pic);
  EXPECT_EQ(map_image_difference(image.image, triangles.image).differing, 0u);
  // The map is drawn: the grid's centre has the colour of its deviation there, not the background's.
  const double x = f.surface.x(30), y = f.surface.y(20);
  const Eigen::Vector2d p = image.pixel({x, y, f.surface.z_mm(20, 30)});
  const Rgb c = table_colour(f.deviation.z_mm(20, 30), 0.010);
  EXPECT_LE(test::colour_distance(image.image.at(static_cast<int>(p.x()), static_cast<int>(p.y())),
                                  test::to8(c[0], c[1], c[2])),
            6);
}
