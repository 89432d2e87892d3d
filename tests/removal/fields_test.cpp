// Dexel fields against analytic references: the groove of one ball-end pass (a circle), the scallops of parallel
// passes (R - sqrt(R^2 - s^2/4)), the floor and wall of a flat end; and the three fields against each other.
#include "removal/fields.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <cstring>

using namespace vmsim::removal;

namespace {

Tool ball(double R) {
  Tool t;
  t.radius_mm = R;
  t.corner_radius_mm = R;
  t.length_mm = 40;
  return t;
}

Tool flat(double R) {
  Tool t;
  t.radius_mm = R;
  t.corner_radius_mm = 0;
  t.length_mm = 40;
  return t;
}

SweptTool line(const Tool& t, Eigen::Vector3d a, Eigen::Vector3d b) {
  SweptTool s;
  s.tool = t;
  s.tip0 = a;
  s.d = b - a;
  return s;
}

Box box(double x0, double y0, double z0, double x1, double y1, double z1) {
  return Box{Eigen::Vector3d(x0, y0, z0), Eigen::Vector3d(x1, y1, z1)};
}

}  // namespace

// One straight ball-end pass along X at depth 1 mm: at every node whose x lies away from the pass' ends, the height
// is the circle z = z_tip + R - sqrt(R^2 - (y - y0)^2) inside the groove and the stock's top outside.
TEST(Fields, OneBallPassLeavesACircularGroove) {
  const double R = 5, top = 10, z_tip = 9, y0 = 10.03;
  const Box stock = box(0, 0, 0, 40, 20, top);
  DexelGrid z = make_zmap(stock, 0.05);
  fill_box(z, stock);
  cut(z, {line(ball(R), {-10, y0, z_tip}, {50, y0, z_tip})});
  const vmsim::core::HeightGrid h = height_grid(z);
  double worst = 0;
  for (Eigen::Index j = 0; j < h.ny(); ++j) {
    for (Eigen::Index i = 0; i < h.nx(); ++i) {
      const double dy = h.y(j) - y0;
      const double expected = std::abs(dy) < R ? std::min(top, z_tip + R - std::sqrt(R * R - dy * dy)) : top;
      worst = std::max(worst, std::abs(h.z_mm(j, i) - expected));
    }
  }
  EXPECT_LE(worst, 1e-4);  // 0.1 um
  RecordProperty("worst_error_mm", std::to_string(worst));
}

// Parallel passes s apart leave scallops of height R - sqrt(R^2 - s^2/4) between them: every node equals the
// lower envelope of the passes' circles.
TEST(Fields, ParallelPassesLeaveScallops) {
  const double R = 5, s = 0.25, z_tip = 0, top = 2;
  const Box stock = box(0, 0, -5, 20, 10, top);
  DexelGrid z = make_zmap(stock, 1.0 / 64);
  fill_box(z, stock);
  std::vector<SweptTool> passes;
  std::vector<double> ys;
  for (double y = -1; y <= 11.0001; y += s) {
    passes.push_back(line(ball(R), {-10, y, z_tip}, {30, y, z_tip}));
    ys.push_back(y);
  }
  cut(z, passes);
  const vmsim::core::HeightGrid h = height_grid(z);
  double worst = 0, highest = 0;
  for (Eigen::Index j = 0; j < h.ny(); ++j) {
    double expected = top;
    for (double y : ys) {
      const double dy = h.y(j) - y;
      if (std::abs(dy) < R) expected = std::min(expected, z_tip + R - std::sqrt(R * R - dy * dy));
    }
    for (Eigen::Index i = 0; i < h.nx(); ++i) worst = std::max(worst, std::abs(h.z_mm(j, i) - expected));
    highest = std::max(highest, h.z_mm(j, h.nx() / 2) - z_tip);
  }
  EXPECT_LE(worst, 1e-4);
  // The scallop height itself, R - sqrt(R^2 - s^2/4) = 1.5628 um, is reached on the grid to within the grid's
  // sampling of the cusp (nodes every 1/64 mm).
  const double scallop = R - std::sqrt(R * R - s * s / 4);
  EXPECT_NEAR(highest, scallop, 2e-5);
  EXPECT_LE(highest, scallop + 1e-7);
}

// A flat end: an exact floor inside the slot, the walls at +-R seen by the tri-dexel's horizontal rays.
TEST(Fields, FlatEndLeavesAnExactFloorAndWalls) {
  const Box stock = box(0, 0, 0, 30, 20, 10);
  TriDexel t = make_tridexel(stock, 0.1);
  for (DexelGrid* g : {&t.x, &t.y, &t.z}) fill_box(*g, stock);
  const std::vector<SweptTool> sw = {line(flat(4), {-10, 10, 6}, {40, 10, 6})};
  for (DexelGrid* g : {&t.x, &t.y, &t.z}) cut(*g, sw);
  const vmsim::core::HeightGrid h = height_grid(t.z);
  for (Eigen::Index j = 0; j < h.ny(); ++j) {
    const double y = h.y(j);
    if (std::abs(std::abs(y - 10) - 4) < 1e-6) continue;  // rays exactly on the wall only graze the tool
    const double expected = std::abs(y - 10) < 4 ? 6.0 : 10.0;
    for (Eigen::Index i = 0; i < h.nx(); ++i) ASSERT_NEAR(h.z_mm(j, i), expected, 1e-5) << "y=" << y;
  }
  // Y rays at heights inside the slot: material on [0, 6] and [14, 20] in y (the walls at 10 -+ 4).
  std::vector<Interval> iv;
  const int iz = 80;  // z = 8
  for (int ix = 0; ix < t.y.nv(); ix += 17) {
    t.y.intervals(iz, ix, iv);  // y-grid: U = Z, V = X
    ASSERT_EQ(iv.size(), 2u);
    EXPECT_NEAR(iv[0].hi, 6.0, 1e-5);
    EXPECT_NEAR(iv[1].lo, 14.0, 1e-5);
  }
}

// Tri-dexel, z-map and N-buffer agree where they overlap: after the same ball-end moves in several directions, the
// heights of the z-map, of the tri-dexel's Z grid and of vertical needles at the same points are identical, and
// the X and Y grids' rays end where the Z grid says the surface is.
TEST(Fields, ZmapTridexelAndNeedlesAgree) {
  const Box stock = box(0, 0, 0, 20, 20, 10);
  const double h = 0.2;
  DexelGrid zm = make_zmap(stock, h);
  TriDexel td = make_tridexel(stock, h);
  std::vector<Eigen::Vector3d> o, d;
  std::vector<double> len;
  for (int j = 0; j < zm.nv(); j += 3)
    for (int i = 0; i < zm.nu(); i += 3) {
      o.push_back(zm.ray_origin(i, j));
      d.push_back(Eigen::Vector3d::UnitZ());
      len.push_back(10);
    }
  NeedleSet nd(o, d, len);
  fill_box(zm, stock);
  for (DexelGrid* g : {&td.x, &td.y, &td.z}) fill_box(*g, stock);
  fill_box(nd, stock);
  const std::vector<SweptTool> sw = {line(ball(3), {2, 3, 8}, {17, 6, 7}), line(ball(3), {17, 6, 7}, {10, 17, 8.5}),
                                     line(ball(3), {10, 17, 8.5}, {2, 3, 8})};
  cut(zm, sw);
  for (DexelGrid* g : {&td.x, &td.y, &td.z}) cut(*g, sw);
  cut(nd, sw);
  std::size_t k = 0;
  for (int j = 0; j < zm.nv(); j += 3)
    for (int i = 0; i < zm.nu(); i += 3, ++k) {
      ASSERT_EQ(zm.top(i, j), td.z.top(i, j));
      ASSERT_EQ(zm.top(i, j), nd.store().top(k));
    }
  // X rays at (y, z): wherever the Z grid's surface at (x, y) is below z, the X ray at that height has no
  // material at x (to within the grids' float resolution).
  std::vector<Interval> iv;
  int compared = 0;
  for (int jz = 0; jz < td.x.nv(); jz += 4) {
    const double z = jz * h;
    for (int iy = 0; iy < td.x.nu(); iy += 4) {
      td.x.intervals(iy, jz, iv);
      for (int ix = 0; ix < td.z.nu(); ix += 4) {
        const double x = ix * h, surface = td.z.top(ix, iy);
        bool material = false;
        for (const Interval& a : iv) material = material || (x > a.lo + 1e-5 && x < a.hi - 1e-5);
        if (z > surface + 1e-4) {
          EXPECT_FALSE(material) << x << " " << iy * h << " " << z;
        }
        if (z < surface - 1e-4 && (x > 0.5 && x < 19.5)) {
          EXPECT_TRUE(material) << x << " " << iy * h << " " << z;
        }
        ++compared;
      }
    }
  }
  EXPECT_GT(compared, 1000);
}

TEST(Fields, ResultDoesNotDependOnTheThreadCount) {
  const Box stock = box(0, 0, 0, 30, 30, 10);
  std::vector<SweptTool> sw;
  for (int k = 0; k < 40; ++k)
    sw.push_back(line(ball(4), {1.0 + k * 0.7, 2, 9 - 0.05 * k}, {29 - k * 0.3, 28, 8.5 + 0.03 * k}));
  auto run = [&](int threads) {
    omp_set_num_threads(threads);
    DexelGrid z = make_zmap(stock, 0.1);
    fill_box(z, stock);
    cut(z, sw);
    return height_grid(z);
  };
  const auto a = run(1), b = run(2);
  omp_set_num_threads(omp_get_num_procs());
  ASSERT_EQ(a.z_mm.size(), b.z_mm.size());
  EXPECT_TRUE((a.z_mm == b.z_mm).all());
}

// Memory: a z-map ray with one interval costs 8 bytes plus the overflow table's small fixed overhead.
TEST(Fields, ZmapCostsEightBytesPerDexel) {
  const Box stock = box(0, 0, 0, 100, 100, 10);
  DexelGrid z = make_zmap(stock, 0.1);
  fill_box(z, stock);
  const double per = static_cast<double>(z.memory_bytes()) / (static_cast<double>(z.nu()) * z.nv());
  EXPECT_LE(per, 8.0 + 0.1);
  RecordProperty("bytes_per_dexel", std::to_string(per));
}

#include "removal/row_bounds.hpp"

// The z-map kernel's vectorised part is built twice (plain and AVX2, picked at run time): both must give the same
// bits, or results would depend on the CPU.
TEST(Fields, VectorisedKernelIsIdenticalOnEveryCpu) {
  if (!__builtin_cpu_supports("avx2")) GTEST_SKIP() << "this CPU has no AVX2";
  double a[300], b[300], d[300], e[300];
  int idx[300];
  for (int k = 0; k < 300; ++k) idx[k] = (k * 7) % 300;
  for (int trial = 0; trial < 50; ++trial) {
    const double s = trial * 0.37;
    vmsim::removal::RowCutParams p{5,   40,      3 - s, 0.7 + s, -0.2 * s, 0.49 + s * s, 1 / (0.49 + s * s),
                                   1.1, 0.3 - s, 0.4,   1 + s,   0.0625};
    vmsim::removal::row_bounds_generic(p, 0.9 - s, -7, idx, 300, a, b);
    vmsim::removal::row_bounds_avx2(p, 0.9 - s, -7, idx, 300, d, e);
    for (int k = 0; k < 300; ++k) {
      ASSERT_EQ(std::memcmp(&a[k], &d[k], 8), 0) << trial << " " << k;
      ASSERT_EQ(std::memcmp(&b[k], &e[k], 8), 0);
    }
    vmsim::removal::row_prefilter_generic(p, 0.9 - s, -7, 300, a);
    vmsim::removal::row_prefilter_avx2(p, 0.9 - s, -7, 300, d);
    for (int k = 0; k < 300; ++k) ASSERT_EQ(std::memcmp(&a[k], &d[k], 8), 0) << trial << " " << k;
  }
}
