// Tiles of a dexel field (removal/fields.hpp Tile, DexelGrid::v_first): a tile is a band of rows of the one lattice,
// cut only with the sweeps that reach it (sweeps_reaching). Reference: the whole field cut with every sweep, in
// this same test; every ray of every tile must hold exactly (bit for bit) the intervals of the same ray of the
// whole field, for z-map and tri-dexel grids, ball, flat and bull-nose tools, vertical and tilted tool axes (the
// axial fast path and the general ray kernel).
#include "removal/fields.hpp"

#include "core/error.hpp"
#include "tests/removal/removal_test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <random>

using namespace vmsim::removal;

namespace {

using vmsim::removal::test::tool;

// Random moves over and into a 40 x 30 x 12 box: short and long, vertical axis and tilted by up to 40 deg.
std::vector<SweptTool> random_sweeps(unsigned seed, int n) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(-5, 45), uy(-5, 35), uz(7, 13), ua(-0.8, 0.8), u01(0, 1);
  std::vector<SweptTool> s;
  Eigen::Vector3d p(ux(rng), uy(rng), uz(rng));
  for (int k = 0; k < n; ++k) {
    const int kind = k % 3;
    SweptTool w;
    w.tool = kind == 0 ? tool(3, 3) : kind == 1 ? tool(2.5, 0) : tool(3, 1);
    const bool tilt = u01(rng) < 0.3;
    w.axis = tilt ? Eigen::Vector3d(ua(rng), ua(rng), 1).normalized() : Eigen::Vector3d::UnitZ();
    const double len = u01(rng) < 0.5 ? 2.0 : 25.0;
    Eigen::Vector3d q = p + len * Eigen::Vector3d(u01(rng) - 0.5, u01(rng) - 0.5, 0.2 * (u01(rng) - 0.5));
    q.z() = std::clamp(q.z(), 6.0, 13.0);
    w.tip0 = p;
    w.d = q - p;
    s.push_back(w);
    p = q;
    if (p.x() < -5 || p.x() > 45 || p.y() < -5 || p.y() > 35) p = Eigen::Vector3d(ux(rng), uy(rng), uz(rng));
  }
  return s;
}

using vmsim::removal::test::same_bits;

// Every ray of `tile` against the whole grid's ray at the same lattice row.
void expect_tile_equals_whole(const DexelGrid& whole, const DexelGrid& tile, const std::string& what) {
  ASSERT_EQ(whole.nu(), tile.nu());
  std::vector<Interval> a, b;
  std::size_t nonempty = 0;
  for (int j = 0; j < tile.nv(); ++j)
    for (int i = 0; i < tile.nu(); ++i) {
      whole.intervals(i, tile.v_first() + j, a);
      tile.intervals(i, j, b);
      ASSERT_TRUE(same_bits(a, b)) << what << ": ray (" << i << ", " << tile.v_first() + j << ")";
      nonempty += !b.empty();
    }
  EXPECT_GT(nonempty, 0u) << what;
}

}  // namespace

TEST(Tiles, RowsSplitEvenlyAndTooManyTilesIsAnError) {
  int next = 0;
  for (int r = 0; r < 3; ++r) {
    const auto [a, b] = tile_rows(10, Tile{r, 3});
    EXPECT_EQ(a, next);
    EXPECT_GE(b - a, 3);
    next = b;
  }
  EXPECT_EQ(next, 10);
  EXPECT_THROW(tile_rows(2, Tile{0, 3}), vmsim::core::Error);
}

TEST(Tiles, ZmapTileCutWithItsSweepsEqualsTheWholeField) {
  const Box stock{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(40, 30, 10)};
  const double h = 0.25;
  const std::vector<SweptTool> sweeps = random_sweeps(7, 80);
  DexelGrid whole = make_zmap(stock, h);
  fill_box(whole, stock);
  cut(whole, sweeps);
  for (const int n : {2, 3}) {
    std::size_t culled = 0;
    for (int r = 0; r < n; ++r) {
      DexelGrid t = make_zmap(stock, h, Tile{r, n});
      fill_box(t, stock);
      const std::vector<SweptTool> mine = sweeps_reaching(t, sweeps);
      culled += sweeps.size() - mine.size();
      cut(t, mine);
      expect_tile_equals_whole(whole, t, "z-map tile " + std::to_string(r) + " of " + std::to_string(n));
    }
    EXPECT_GT(culled, 0u) << "no tile of " << n << " left any sweep out: the culling is not exercised";
  }
}

TEST(Tiles, TridexelTilesCutWithTheirSweepsEqualTheWholeField) {
  const Box stock{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(40, 30, 10)};
  const double h = 0.4;
  const std::vector<SweptTool> sweeps = random_sweeps(11, 90);
  TriDexel whole = make_tridexel(stock, h);
  for (DexelGrid* g : {&whole.x, &whole.y, &whole.z}) fill_box(*g, stock), cut(*g, sweeps);
  const int n = 3;
  for (int r = 0; r < n; ++r) {
    TriDexel t = make_tridexel(stock, h, Tile{r, n});
    const DexelGrid* w[3] = {&whole.x, &whole.y, &whole.z};
    DexelGrid* g[3] = {&t.x, &t.y, &t.z};
    for (int k = 0; k < 3; ++k) {
      fill_box(*g[k], stock);
      cut(*g[k], sweeps_reaching(*g[k], sweeps));
      expect_tile_equals_whole(*w[k], *g[k], "tri-dexel grid " + std::to_string(k) + ", tile " + std::to_string(r));
    }
  }
}

// The band's height grid sits where the whole grid's rows are.
TEST(Tiles, HeightGridOfATileIsItsBandOfTheWhole) {
  const Box stock{Eigen::Vector3d(-3, 2, 0), Eigen::Vector3d(10, 12, 5)};
  DexelGrid whole = make_zmap(stock, 0.5);
  DexelGrid t = make_zmap(stock, 0.5, Tile{1, 2});
  fill_box(whole, stock);
  fill_box(t, stock);
  const vmsim::core::HeightGrid hw = height_grid(whole), ht = height_grid(t);
  EXPECT_EQ(ht.nx(), hw.nx());
  EXPECT_DOUBLE_EQ(ht.y0_mm, hw.y(t.v_first()));
  EXPECT_DOUBLE_EQ(ht.x0_mm, hw.x0_mm);
}
