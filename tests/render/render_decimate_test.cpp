// The per-pixel-column envelope (M4) a chart draws instead of all its points. Reference: the polyline itself, sampled
// densely segment by segment: per pixel column, the lowest and highest y the drawn line passes through must be the
// same for the reduced line as for the whole one (that is what a raster of that width can show), and the line must
// break where the data has a NaN.
#include "render/chart.hpp"
#include "render/decimate.hpp"
#include "render_test_support.hpp"

#include "core/error.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <utility>

using namespace vmsim;
using namespace vmsim::render;

namespace {

// Per column: (lowest, highest) y the polyline covers, from 32 samples per segment; NaN points break it.
std::map<long, std::pair<double, double>> m4test_column_extent(const Eigen::ArrayXd& x, const Eigen::ArrayXd& y,
                                                               double lo, double hi, int columns) {
  std::map<long, std::pair<double, double>> ext;
  auto add = [&](double px, double py) {
    const long c = static_cast<long>(std::floor((px - lo) * columns / (hi - lo)));
    auto [it, fresh] = ext.try_emplace(c, py, py);
    if (!fresh) it->second.first = std::min(it->second.first, py), it->second.second = std::max(it->second.second, py);
  };
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) continue;
    add(x[i], y[i]);
    if (i + 1 < x.size() && std::isfinite(x[i + 1]) && std::isfinite(y[i + 1]))
      for (int k = 1; k < 32; ++k) {
        const double t = k / 32.0;
        add(x[i] + t * (x[i + 1] - x[i]), y[i] + t * (y[i + 1] - y[i]));
      }
  }
  return ext;
}

// A random walk with bursts, sampled unevenly in x (as bins of a signal are, and as a path's distance is).
std::pair<Eigen::ArrayXd, Eigen::ArrayXd> m4test_walk(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> step(0.0, 1.0);
  std::uniform_real_distribution<double> dx(0.1, 1.9);
  Eigen::ArrayXd x(n), y(n);
  double xv = 0, yv = 0;
  for (int i = 0; i < n; ++i) {
    xv += dx(rng);
    yv += step(rng) * (i % 997 < 20 ? 30.0 : 1.0);
    x[i] = xv, y[i] = yv;
  }
  return {x, y};
}

}  // namespace

TEST(ColumnEnvelope, SameExtentPerColumnAsTheWholeLine) {
  const auto [x, y] = m4test_walk(20000, 7);
  const double lo = x[0], hi = x[x.size() - 1];
  for (int columns : {37, 300, 1460}) {
    const Polyline r = column_envelope(x, y, lo, hi, columns);
    EXPECT_LE(r.x.size(), 4 * (columns + 1)) << columns;
    // The first and last points stay, and every kept point is one of the line's, in order.
    EXPECT_EQ(r.x[0], x[0]);
    EXPECT_EQ(r.y[r.y.size() - 1], y[y.size() - 1]);
    for (Eigen::Index k = 1; k < r.x.size(); ++k) ASSERT_GE(r.x[k], r.x[k - 1]);
    const auto whole = m4test_column_extent(x, y, lo, hi, columns);
    const auto reduced = m4test_column_extent(r.x, r.y, lo, hi, columns);
    ASSERT_EQ(whole.size(), reduced.size()) << columns;
    for (const auto& [c, e] : whole) {
      const auto it = reduced.find(c);
      ASSERT_NE(it, reduced.end()) << "column " << c;
      // Equal but for the last bit of a sample between two points (y0 + t (y1 - y0) may round past y1).
      EXPECT_NEAR(it->second.first, e.first, 1e-12 * (1 + std::abs(e.first))) << "lowest y, column " << c;
      EXPECT_NEAR(it->second.second, e.second, 1e-12 * (1 + std::abs(e.second))) << "highest y, column " << c;
    }
  }
}

TEST(ColumnEnvelope, BinnedMinMaxPairsKeepEveryBinsPeak) {
  // What result_images draws: per bin its minimum then its maximum at the bin's mid x (10 000 bins, ~7 a column).
  const int bins = 10000, columns = 1460;
  Eigen::ArrayXd x(2 * bins), y(2 * bins);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int b = 0; b < bins; ++b) {
    const double a = u(rng), c = u(rng);
    x[2 * b] = x[2 * b + 1] = b + 0.5;
    y[2 * b] = std::min(a, c) * (b % 1000 == 0 ? 9 : 1);
    y[2 * b + 1] = std::max(a, c) * (b % 1000 == 0 ? 9 : 1);
  }
  const Polyline r = column_envelope(x, y, 0, bins, columns);
  EXPECT_LT(r.x.size(), 4 * columns + 1);
  EXPECT_LT(r.x.size(), x.size() / 3);  // 20 000 points become fewer than 5 841
  // Per column, the lowest and highest bin value among the bins whose mid x falls in it, found directly.
  std::map<long, std::pair<double, double>> want;
  for (int b = 0; b < bins; ++b) {
    const long c = static_cast<long>(std::floor((b + 0.5) * columns / bins));
    auto [it, fresh] = want.try_emplace(c, y[2 * b], y[2 * b + 1]);
    if (!fresh)
      it->second.first = std::min(it->second.first, y[2 * b]),
      it->second.second = std::max(it->second.second, y[2 * b + 1]);
  }
  std::map<long, std::pair<double, double>> got;
  for (Eigen::Index k = 0; k < r.x.size(); ++k) {
    const long c = static_cast<long>(std::floor(r.x[k] * columns / bins));
    auto [it, fresh] = got.try_emplace(c, r.y[k], r.y[k]);
    if (!fresh)
      it->second.first = std::min(it->second.first, r.y[k]), it->second.second = std::max(it->second.second, r.y[k]);
  }
  EXPECT_EQ(got, want);
}

TEST(ColumnEnvelope, NanBreaksStayAndSparseLinesAreKeptWhole) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Eigen::ArrayXd x(9), y(9);
  x << 0, 1, 2, nan, 4, 5, 6, 7, 8;
  y << 0, 1, 0, 3, nan, 1, nan, 2, 1;
  // 100 columns over [0, 8]: every point its own column, so everything finite is kept; each run of NaN points is one
  // break.
  const Polyline r = column_envelope(x, y, 0, 8, 100);
  ASSERT_EQ(r.x.size(), 8);
  const double want_x[] = {0, 1, 2, nan, 5, nan, 7, 8};
  for (int k = 0; k < 8; ++k) {
    if (std::isnan(want_x[k])) {
      EXPECT_TRUE(std::isnan(r.x[k]) && std::isnan(r.y[k])) << k;
    } else {
      EXPECT_EQ(r.x[k], want_x[k]) << k;
    }
  }
  // Leading and trailing NaNs leave no break at the ends.
  Eigen::ArrayXd x2(4), y2(4);
  x2 << nan, 1, 2, nan;
  y2 << 1, 1, 2, 2;
  const Polyline r2 = column_envelope(x2, y2, 0, 3, 10);
  ASSERT_EQ(r2.x.size(), 2);
  EXPECT_EQ(r2.x[0], 1);
  EXPECT_EQ(r2.x[1], 2);
}

TEST(ColumnEnvelope, RejectsMismatchedOrEmptyRanges) {
  const Eigen::ArrayXd x = Eigen::ArrayXd::LinSpaced(5, 0, 4), y = Eigen::ArrayXd::Zero(4);
  EXPECT_THROW(column_envelope(x, y, 0, 4, 10), core::Error);
  EXPECT_THROW(column_envelope(x, x, 0, 4, 0), core::Error);
  EXPECT_THROW(column_envelope(x, x, 4, 4, 10), core::Error);
  EXPECT_THROW(column_envelope(x, x, 0, std::numeric_limits<double>::infinity(), 10), core::Error);
}

// A chart of 400 000 noisy points: drawn from its envelope, the curve still reaches the data's extremes. Reference:
// the data's own min and max, located in the chart's frame.
TEST(ColumnEnvelope, ChartOfManyPointsShowsItsExtremes) {
  const auto [x, y] = m4test_walk(400000, 11);
  ChartPicture pic;
  pic.width = 800, pic.height = 450;
  Chart c;
  c.x_title = "t [s]";
  c.y_title = "e [µm]";
  c.series.push_back(make_series("walk", x, y, 0, 1.0));
  c.legend = false;
  pic.charts.push_back(c);
  const ChartImage img = render_charts(test::shared_window(), pic);
  const ChartFrame& f = img.frames[0];
  const Rgb c0 = series_colour(0);
  const Rgb8 blue = test::to8(c0[0], c0[1], c0[2]);
  Eigen::Index imax = 0, imin = 0;
  y.maxCoeff(&imax);
  y.minCoeff(&imin);
  for (Eigen::Index i : {imax, imin}) {
    const Eigen::Vector2d p = f.pixel(x[i], y[i]);
    EXPECT_LT(test::nearest_match(img.image, p.x(), p.y(), blue, 2), 80) << "extreme at x " << x[i] << " missing";
  }
  test::keep_if_failed(img.image);
}
