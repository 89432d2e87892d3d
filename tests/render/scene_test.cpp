// Part pictures, checked by their pixels (no snapshots): the reference of every colour check is the colour map's
// own definition (render/colormap), applied to analytic deviations whose value at a point is known exactly.
#include "render/colormap.hpp"
#include "render/scene.hpp"
#include "render_test_support.hpp"

#include "core/error.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace vmsim;
using namespace vmsim::render;
using render::test::shared_window;

namespace {

// A flat plate 20 x 10 mm at z = 0, 0.05 mm spacing.
core::HeightGrid plate(double z = 0.0) {
  core::HeightGrid g;
  g.x0_mm = 0, g.y0_mm = 0, g.dx_mm = 0.05, g.dy_mm = 0.05;
  g.z_mm = core::HeightArray::Constant(201, 401, z);
  return g;
}

// The analytic groove: a circular groove of radius R and depth d along Y at x = xc (an overcut, negative), and a
// ridge of +h, 2 mm wide, along Y at x = xr (an undercut): deviation(x) in mm.
struct Groove {
  double R = 3.0, depth = 0.008, xc = 6.0, xr = 14.0, h = 0.005;
  double operator()(double x) const {
    double v = 0;
    const double half = std::sqrt(depth * (2 * R - depth));  // half width of the circular groove
    if (std::abs(x - xc) < half) v = -(depth - (R - std::sqrt(R * R - (x - xc) * (x - xc))));
    if (std::abs(x - xr) < 1.0) v = h * (1 - (x - xr) * (x - xr));  // parabolic ridge
    return v;
  }
};

core::HeightGrid groove_deviation(const core::HeightGrid& s, const Groove& g) {
  core::HeightGrid d = s;
  for (Eigen::Index j = 0; j < d.ny(); ++j)
    for (Eigen::Index i = 0; i < d.nx(); ++i) d.z_mm(j, i) = g(d.x(i));
  return d;
}

Rgb8 expected(double v_mm, double limit_mm) {
  const Rgb c = table_colour(v_mm, limit_mm);
  return test::to8(c[0], c[1], c[2]);
}

}  // namespace

TEST(Scene, PlainPartIsNotUniformAndStandsOutOfTheBackground) {
  core::HeightGrid s = plate();
  // A bump, so that the raking light has something to show.
  for (Eigen::Index j = 0; j < s.ny(); ++j)
    for (Eigen::Index i = 0; i < s.nx(); ++i)
      s.z_mm(j, i) = 0.3 * std::exp(-std::pow(s.x(i) - 10, 2) - std::pow(s.y(j) - 5, 2));
  PartPicture pic;
  pic.width = 480, pic.height = 360;
  pic.caption = {"plate with a bump"};
  const PartImage img = render_part(shared_window(), s, nullptr, pic);
  ASSERT_EQ(img.image.width, 480);
  ASSERT_EQ(img.image.height, 360);
  EXPECT_GT(test::distinct_colours(img.image), 200u);
  // The part's centre is drawn (grey metal), not the dark background: R, G, B close to each other and brighter
  // than the background behind it.
  const Eigen::Vector2d c = img.pixel({10, 5, s.z_mm(100, 200)});
  ASSERT_GT(c.x(), 0);
  ASSERT_LT(c.x(), 480);
  const Rgb8 p = img.image.at(static_cast<int>(c.x()), static_cast<int>(c.y()));
  EXPECT_GT(p[0], 60) << int(p[0]) << " " << int(p[1]) << " " << int(p[2]);
  const Rgb8 bg = img.image.at(2, 358);
  EXPECT_LT(bg[0], 60);
}

// The deviation map of a known groove and ridge: at sampled points across them, the pixel has the colour the map
// gives the analytic deviation there.
TEST(Scene, DeviationMapOfAnalyticGrooveMatchesItsColourMap) {
  const core::HeightGrid s = plate();
  const Groove gr;
  const core::HeightGrid d = groove_deviation(s, gr);
  PartPicture pic;
  pic.width = 800, pic.height = 480;
  pic.view.direction = ViewDirection::Top;
  pic.deviation = DeviationColours{};
  pic.deviation->lit = false;
  pic.deviation->limit_mm = 0.010;
  const PartImage img = render_part(shared_window(), s, &d, pic);
  EXPECT_DOUBLE_EQ(img.limit_mm, 0.010);
  int checked = 0;
  for (double x = 0.6; x < 19.5; x += 0.37) {
    for (double y : {2.5, 5.0, 7.5}) {
      // Avoid the two kinks of the groove's edges, where the linear interpolation between nodes departs from the
      // analytic value by more than the table's step.
      const double v = gr(x);
      if (std::abs(gr(x + 0.06) - v) > 4e-4 || std::abs(gr(x - 0.06) - v) > 4e-4) continue;
      const Eigen::Vector2d p = img.pixel({x, y, 0.0});
      const Rgb8 got = img.image.at(static_cast<int>(p.x()), static_cast<int>(p.y()));
      const Rgb8 want = expected(v, 0.010);
      EXPECT_LE(test::colour_distance(got, want), 6)
          << "x " << x << " y " << y << " deviation " << v * 1e3 << " um: got " << int(got[0]) << "," << int(got[1])
          << "," << int(got[2]) << " want " << int(want[0]) << "," << int(want[1]) << "," << int(want[2]);
      ++checked;
    }
  }
  EXPECT_GT(checked, 100);
  // The groove's bottom is blue (overcut), the ridge's top red (undercut), the plate white.
  const Eigen::Vector2d pg = img.pixel({gr.xc, 5, 0}), pr = img.pixel({gr.xr, 5, 0}), pw = img.pixel({10, 5, 0});
  const Rgb8 blue = img.image.at(int(pg.x()), int(pg.y())), red = img.image.at(int(pr.x()), int(pr.y()));
  const Rgb8 white = img.image.at(int(pw.x()), int(pw.y()));
  EXPECT_GT(blue[2], blue[0] + 60);
  EXPECT_GT(red[0], red[2] + 60);
  EXPECT_GT(std::min({white[0], white[1], white[2]}), 240);
}

TEST(Scene, AutomaticLimitIsMaxAbsoluteDeviationRoundedUp) {
  const core::HeightGrid s = plate();
  const core::HeightGrid d = groove_deviation(s, Groove{});  // max |dev| 8 um -> 10 um
  PartPicture pic;
  pic.width = 320, pic.height = 240;
  pic.view.direction = ViewDirection::Top;
  pic.deviation = DeviationColours{};
  pic.deviation->lit = false;
  EXPECT_DOUBLE_EQ(render_part(shared_window(), s, &d, pic).limit_mm, 0.010);
}

// The pixel over a vertex of known deviation of a mesh (not a grid) has the map's colour, in a 3-D view with a
// vertical exaggeration: checks the camera mapping as well as the colours.
TEST(Scene, MeshVertexColourInIsometricViewWithExaggeration) {
  // A 10 x 10 mm plate of 41 x 41 vertices with a raised plateau (z = 1) whose deviation is a linear ramp in x.
  core::TriangleMesh m;
  const int n = 41;
  m.vertices_mm.resize(n * n, 3);
  Eigen::VectorXd dev(n * n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double x = i * 0.25, y = j * 0.25;
      const bool plateau = x > 3 && x < 7 && y > 3 && y < 7;
      m.vertices_mm.row(j * n + i) << x, y, plateau ? 1.0 : 0.0;
      dev[j * n + i] = 0.002 * (x - 5);  // -10 .. +10 um
    }
  m.triangles.resize(2 * (n - 1) * (n - 1), 3);
  int t = 0;
  for (int j = 0; j + 1 < n; ++j)
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i, b = a + 1, c = a + n + 1, d = a + n;
      m.triangles.row(t++) << a, b, c;
      m.triangles.row(t++) << a, c, d;
    }
  m.point_data.emplace_back("deviation_mm", dev);
  PartPicture pic;
  pic.width = 640, pic.height = 480;
  pic.view.direction = ViewDirection::Isometric;
  pic.view.vertical_exaggeration = 2.0;
  pic.deviation = DeviationColours{};
  pic.deviation->lit = false;
  pic.deviation->limit_mm = 0.010;
  const PartImage img = render_part(shared_window(), m, pic);
  int checked = 0;
  for (double x : {3.6, 4.2, 5.0, 5.8, 6.4})
    for (double y : {3.6, 5.0, 6.4}) {
      const Eigen::Vector2d p = img.pixel({x, y, 1.0});
      const Rgb8 got = img.image.at(int(p.x()), int(p.y()));
      const Rgb8 want = expected(0.002 * (x - 5), 0.010);
      EXPECT_LE(test::colour_distance(got, want), 8) << "x " << x << " y " << y;
      ++checked;
    }
  EXPECT_EQ(checked, 15);
}

TEST(Scene, IsolinesAreDrawnWhereTheDeviationCrossesTheirValue) {
  const core::HeightGrid s = plate();
  core::HeightGrid d = s;
  for (Eigen::Index j = 0; j < d.ny(); ++j)
    for (Eigen::Index i = 0; i < d.nx(); ++i) d.z_mm(j, i) = 0.001 * (d.x(i) - 10);  // -10 .. +10 um along x
  PartPicture pic;
  pic.width = 800, pic.height = 480;
  pic.view.direction = ViewDirection::Top;
  pic.deviation = DeviationColours{};
  pic.deviation->lit = false;
  pic.deviation->limit_mm = 0.010;
  pic.deviation->isolines = 1;  // at -5 and +5 um: x = 5 and x = 15
  const PartImage img = render_part(shared_window(), s, &d, pic);
  for (double x : {5.0, 15.0}) {
    const Eigen::Vector2d p = img.pixel({x, 5, 0});
    EXPECT_LT(test::nearest_match(img.image, p.x(), p.y(), {30, 30, 30}, 2), 40) << "no iso-line at x " << x;
  }
  // ...and nowhere else along that row.
  const Eigen::Vector2d q = img.pixel({10, 5, 0});
  EXPECT_GT(test::nearest_match(img.image, q.x(), q.y(), {30, 30, 30}, 2), 150);
}

TEST(Scene, MarkMagnificationRaisesTheMarkOnly) {
  const core::HeightGrid s = plate();
  const core::HeightGrid d = groove_deviation(s, Groove{});
  PartPicture pic;
  pic.width = 320, pic.height = 240;
  pic.view.direction = ViewDirection::AlongPath;
  pic.view.mark_magnification = 50;
  const PartImage a = render_part(shared_window(), s, &d, pic);
  pic.view.mark_magnification = 1;
  const PartImage b = render_part(shared_window(), s, &d, pic);
  EXPECT_NE(a.image.rgb, b.image.rgb);
  // Meshes carry no reference surface to magnify against.
  core::TriangleMesh m;
  m.vertices_mm.resize(3, 3);
  m.vertices_mm << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  m.triangles.resize(1, 3);
  m.triangles << 0, 1, 2;
  EXPECT_NO_THROW(render_part(shared_window(), m, pic));
  pic.view.mark_magnification = 50;
  EXPECT_THROW(render_part(shared_window(), m, pic), core::Error);
}

TEST(Scene, RegionZoomFramesTheRegion) {
  const core::HeightGrid s = plate();
  const core::HeightGrid d = groove_deviation(s, Groove{});
  PartPicture pic;
  pic.width = 400, pic.height = 300;
  pic.view.direction = ViewDirection::Top;
  pic.view.region = Region{4, 8, 3, 6};
  pic.deviation = DeviationColours{};
  pic.deviation->lit = false;
  const PartImage img = render_part(shared_window(), s, &d, pic);
  // The region's corners land inside the scene viewport, near its edges.
  const Eigen::Vector2d lo = img.pixel({4, 3, 0}), hi = img.pixel({8, 6, 0});
  EXPECT_GE(lo.x(), img.viewport_px[0] - 1);
  EXPECT_LE(hi.x(), img.viewport_px[0] + img.viewport_px[2] + 1);
  EXPECT_GT(hi.x() - lo.x(), 0.8 * img.viewport_px[2]);
}

TEST(Scene, RegionAroundKeepsAspectAndBounds) {
  const Region r = region_around(85, 5, 6, Region{0, 120, 0, 10}, 1600, 1200);
  EXPECT_DOUBLE_EQ(r.y_min_mm, 0);
  EXPECT_DOUBLE_EQ(r.y_max_mm, 10);
  EXPECT_NEAR(r.x_max_mm - r.x_min_mm, 16, 1e-9);
  EXPECT_NEAR((r.x_min_mm + r.x_max_mm) / 2, 85, 1e-9);
  const Region e = region_around(1, 5, 6, Region{0, 120, 0, 10}, 1600, 1200);
  EXPECT_DOUBLE_EQ(e.x_min_mm, 0);
  EXPECT_NEAR(e.x_max_mm, 16, 1e-9);
}

TEST(Scene, BadInputsAreErrorsNotCrashes) {
  const core::HeightGrid s = plate();
  core::HeightGrid other = plate();
  other.dx_mm = 0.1;
  PartPicture pic;
  pic.width = 320, pic.height = 240;
  pic.deviation = DeviationColours{};
  EXPECT_THROW(render_part(shared_window(), s, nullptr, pic), core::Error);  // colours without deviation
  EXPECT_THROW(render_part(shared_window(), s, &other, pic), core::Error);   // another grid
  pic.deviation.reset();
  pic.width = 4;
  EXPECT_THROW(render_part(shared_window(), s, nullptr, pic), core::Error);
  pic.width = 320;
  pic.view.region = Region{200, 300, 0, 10};
  EXPECT_THROW(render_part(shared_window(), s, nullptr, pic), core::Error);
  pic.view.region.reset();
  pic.view.vertical_exaggeration = 0;
  EXPECT_THROW(render_part(shared_window(), s, nullptr, pic), core::Error);
  pic.view.vertical_exaggeration = 1;
  core::HeightGrid holes = plate();
  holes.z_mm.setConstant(NAN);
  EXPECT_THROW(render_part(shared_window(), holes, nullptr, pic), core::Error);
  // A grid with holes renders around them.
  holes = plate();
  holes.z_mm.block(50, 100, 100, 200).setConstant(NAN);
  EXPECT_NO_THROW(render_part(shared_window(), holes, nullptr, pic));
}

// A grid finer than the picture is drawn at every k-th node (PartPicture::full_resolution). Reference: the same
// picture drawn from every node. A 1201 x 901-node wavy part with a groove (0.01 mm spacing) in a 400 x 300 picture
// is drawn at every 3rd node; the pictures must agree but for a small difference at the scale of a pixel (the
// scallops, 15 nodes apart, are sampled at 5 nodes a period).
TEST(Scene, DecimatedGridPictureIsCloseToTheFullResolutionOne) {
  core::HeightGrid s;
  s.dx_mm = s.dy_mm = 0.01;
  s.z_mm.resize(901, 1201);
  const Groove groove;
  for (Eigen::Index j = 0; j < s.ny(); ++j)
    for (Eigen::Index i = 0; i < s.nx(); ++i)
      s.z_mm(j, i) = 0.2 * std::sin(s.x(i) / 1.7) * std::cos(s.y(j) / 1.3) + groove(s.x(i) * 20.0 / 12.0) +
                     0.003 * std::sin(2 * M_PI * s.y(j) / 0.15);  // scallops 5 pixels apart
  core::HeightGrid dev = s;
  for (Eigen::Index j = 0; j < s.ny(); ++j)
    for (Eigen::Index i = 0; i < s.nx(); ++i)
      dev.z_mm(j, i) = groove(s.x(i) * 20.0 / 12.0) + 0.0005 * std::sin(2 * M_PI * s.y(j) / 0.15);
  struct Case {
    const char* name;
    ViewDirection dir;
    bool coloured;
  };
  for (const Case& c : {Case{"isometric metal", ViewDirection::Isometric, false},
                        Case{"top deviation map", ViewDirection::Top, true}}) {
    SCOPED_TRACE(c.name);
    PartPicture pic;
    pic.width = 400, pic.height = 300;
    pic.view.direction = c.dir;
    if (c.coloured) pic.deviation = DeviationColours{0.01, 3, false, ""};
    const PartImage fast = render_part(shared_window(), s, &dev, pic);
    pic.full_resolution = true;
    const PartImage full = render_part(shared_window(), s, &dev, pic);
    ASSERT_EQ(fast.image.rgb.size(), full.image.rgb.size());
    EXPECT_GT(test::distinct_colours(fast.image), 200u);  // not blank
    // Mean and 99th percentile of max-channel |dRGB| over the picture.
    auto difference = [&](const Image& a) {
      std::vector<double> d;
      for (int y = 0; y < full.image.height; ++y)
        for (int x = 0; x < full.image.width; ++x) d.push_back(test::colour_distance(a.at(x, y), full.image.at(x, y)));
      double mean = 0;
      for (double v : d) mean += v / static_cast<double>(d.size());
      std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(0.99 * d.size()), d.end());
      return std::pair{mean, d[static_cast<std::size_t>(0.99 * d.size())]};
    };
    const auto [mean, p99] = difference(fast.image);
    std::printf("%s: mean |dRGB| %.3f, 99th percentile %.0f\n", c.name, mean, p99);
    EXPECT_LT(mean, 1.5);
    EXPECT_LT(p99, 10.0);
    // Control, that the bounds can fail: the grid sampled at every 12th node (4x coarser than the picture's pixels),
    // drawn at full resolution, is further off than them.
    core::HeightGrid coarse = s, coarse_dev = dev;
    coarse.dx_mm = coarse.dy_mm = coarse_dev.dx_mm = coarse_dev.dy_mm = 0.12;
    coarse.z_mm.resize(76, 101), coarse_dev.z_mm.resize(76, 101);
    for (Eigen::Index j = 0; j < 76; ++j)
      for (Eigen::Index i = 0; i < 101; ++i)
        coarse.z_mm(j, i) = s.z_mm(12 * j, 12 * i), coarse_dev.z_mm(j, i) = dev.z_mm(12 * j, 12 * i);
    const auto [cmean, cp99] = difference(render_part(shared_window(), coarse, &coarse_dev, pic).image);
    std::printf("%s, control at every 12th node: mean |dRGB| %.3f, 99th percentile %.0f\n", c.name, cmean, cp99);
    EXPECT_TRUE(cmean > 1.5 || cp99 > 10.0);
    test::keep_if_failed(fast.image, "_fast");
    test::keep_if_failed(full.image, "_full");
  }
}
