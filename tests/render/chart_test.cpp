// Charts, checked by their pixels: a curve is drawn where its data puts it in the chart's frame (and not elsewhere),
// a limit line at its value, a NaN leaves a gap.
#include "render/chart.hpp"
#include "render_test_support.hpp"

#include "core/error.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace vmsim;
using namespace vmsim::render;
using render::test::shared_window;

namespace {

Series sine(int n, double amplitude) {
  Series s;
  s.name = "sine";
  s.x = Eigen::ArrayXd::LinSpaced(n, 0.0, 10.0);
  s.y = amplitude * (s.x * 0.8).sin();
  s.colour = series_colour(0);
  return s;
}

}  // namespace

TEST(Chart, CurveIsWhereTheDataPutsIt) {
  ChartPicture pic;
  pic.width = 800, pic.height = 450;
  pic.caption = {"test chart"};
  Chart c;
  c.title = "a sine";
  c.x_title = "t [s]";
  c.y_title = "v [mm/s]";
  c.series.push_back(sine(2000, 100));
  c.levels.push_back({"limit 120 mm/s", 120.0});
  pic.charts.push_back(c);
  const ChartImage img = render_charts(shared_window(), pic);
  ASSERT_EQ(img.frames.size(), 1u);
  const ChartFrame& f = img.frames[0];
  // The frame is a sensible part of the picture, the x axis spans the data exactly, y includes data and limit.
  EXPECT_GT(f.right_px - f.left_px, 0.7 * pic.width);
  EXPECT_GT(f.bottom_px - f.top_px, 0.5 * pic.height);
  EXPECT_DOUBLE_EQ(f.x_min, 0.0);
  EXPECT_DOUBLE_EQ(f.x_max, 10.0);
  EXPECT_LE(f.y_min, -100.0);
  EXPECT_GE(f.y_max, 120.0);
  const Rgb c0 = series_colour(0);
  const Rgb8 blue = test::to8(c0[0], c0[1], c0[2]);
  for (double x = 0.25; x < 9.8; x += 0.5) {
    const double y = 100 * std::sin(0.8 * x);
    const Eigen::Vector2d p = f.pixel(x, y);
    EXPECT_LT(test::nearest_match(img.image, p.x(), p.y(), blue, 2), 60) << "curve missing at x " << x;
    // 40 px above or below (whichever stays inside the frame), no curve.
    const double off = p.y() - 40 > f.top_px ? -40 : 40;
    EXPECT_GT(test::nearest_match(img.image, p.x(), p.y() + off, blue, 2), 90) << "curve where no data at x " << x;
  }
  // The limit: a red dashed line at y = 120 (column by column, about half of them on a dash), and none 10 px off.
  const Rgb8 red = test::to8(0.8, 0.1, 0.1);
  const double yl = f.pixel(0, 120.0).y();
  int columns = 0, on = 0, off = 0;
  for (int x = static_cast<int>(f.left_px) + 5; x < static_cast<int>(f.right_px) - 5; ++x, ++columns) {
    if (test::nearest_match(img.image, x, yl, red, 1) < 70) ++on;
    if (test::nearest_match(img.image, x, yl + 10, red, 1) < 70) ++off;
  }
  EXPECT_GT(on, columns / 3);
  EXPECT_EQ(off, 0);
  test::keep_if_failed(img.image);
}

TEST(Chart, NanBreaksTheLine) {
  ChartPicture pic;
  pic.width = 640, pic.height = 360;
  Chart c;
  c.x_title = "s [mm]";
  c.y_title = "e [µm]";
  Series s;
  s.x = Eigen::ArrayXd::LinSpaced(101, 0, 100);
  s.y = Eigen::ArrayXd::Constant(101, 5.0);
  s.y.segment(40, 21).setConstant(NAN);  // x 40..60
  s.colour = series_colour(0);
  c.series.push_back(s);
  c.legend = false;
  c.y_range = std::make_pair(0.0, 10.0);
  pic.charts.push_back(c);
  const ChartImage img = render_charts(shared_window(), pic);
  const ChartFrame& f = img.frames[0];
  EXPECT_DOUBLE_EQ(f.y_min, 0.0);
  EXPECT_DOUBLE_EQ(f.y_max, 10.0);
  const Rgb8 blue = test::to8(series_colour(0)[0], series_colour(0)[1], series_colour(0)[2]);
  for (double x : {10.0, 30.0, 70.0, 90.0}) {
    const Eigen::Vector2d p = f.pixel(x, 5.0);
    EXPECT_LT(test::nearest_match(img.image, p.x(), p.y(), blue, 2), 60) << x;
  }
  for (double x : {45.0, 50.0, 55.0}) {
    const Eigen::Vector2d p = f.pixel(x, 5.0);
    EXPECT_GT(test::nearest_match(img.image, p.x(), p.y(), blue, 2), 90) << x;
  }
  test::keep_if_failed(img.image);
}

TEST(Chart, StackedChartsEachInTheirBand) {
  ChartPicture pic;
  pic.width = 640, pic.height = 720;
  for (int k = 0; k < 3; ++k) {
    Chart c;
    c.title = "chart " + std::to_string(k);
    c.x_title = "t [s]";
    c.y_title = "y [mm]";
    c.series.push_back(sine(200, 10.0 * (k + 1)));
    pic.charts.push_back(c);
  }
  const ChartImage img = render_charts(shared_window(), pic);
  ASSERT_EQ(img.frames.size(), 3u);
  for (std::size_t k = 0; k + 1 < 3; ++k) EXPECT_LT(img.frames[k].bottom_px, img.frames[k + 1].top_px);
  EXPECT_GE(img.frames[2].y_max, 30.0);
}

TEST(Chart, BadInputsAreErrors) {
  ChartPicture pic;
  pic.width = 320, pic.height = 200;
  EXPECT_THROW(render_charts(shared_window(), pic), core::Error);  // no charts
  Chart c;
  Series s;
  s.x = Eigen::ArrayXd::LinSpaced(3, 0, 1);
  s.y = Eigen::ArrayXd::Zero(2);
  c.series.push_back(s);
  pic.charts.push_back(c);
  EXPECT_THROW(render_charts(shared_window(), pic), core::Error);  // x and y lengths differ
  pic.charts[0].series[0].y = Eigen::ArrayXd::Constant(3, NAN);
  EXPECT_THROW(render_charts(shared_window(), pic), core::Error);  // nothing finite
  pic.charts[0].series[0].y = Eigen::ArrayXd::Zero(3);
  pic.charts[0].x_range = std::make_pair(1.0, 1.0);
  EXPECT_THROW(render_charts(shared_window(), pic), core::Error);  // empty range
  pic.charts[0].x_range.reset();
  EXPECT_NO_THROW(render_charts(shared_window(), pic));  // a flat line is fine
}
