// The counts `vmsim run --plan` predicts the run's CPU time from (sim/time_plan.hpp): the rays in each sweep's shadow,
// by kernel path. Reference: removal::footprint on the grids removal::make_zmap / make_tridexel build (the kernel's
// own culling, computed there from the grid objects, not from the stock box and spacing). No timing is tested here:
// bench/README.md compares predicted and measured CPU.
#include "removal/cut.hpp"
#include "removal/fields.hpp"
#include "sim/time_plan.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <random>

namespace {

using namespace vmsim;

removal::Tool tool(double R, double rc, double L) {
  removal::Tool t;
  t.radius_mm = R, t.corner_radius_mm = rc, t.length_mm = L;
  return t;
}

double footprint_rays(const removal::DexelGrid& g, const std::vector<removal::SweptTool>& sweeps) {
  double n = 0;
  for (const removal::SweptTool& s : sweeps) {
    const removal::Footprint f = removal::footprint(g, s);
    if (!f.empty()) n += double(f.i1 - f.i0 + 1) * double(f.j1 - f.j0 + 1);
  }
  return n;
}

std::vector<removal::SweptTool> random_sweeps(const removal::Tool& t, bool tilted, int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<removal::SweptTool> out;
  for (int k = 0; k < n; ++k) {
    removal::SweptTool s;
    s.tool = t;
    s.tip0 = Eigen::Vector3d(20 + 25 * U(rng), 15 + 20 * U(rng), 8 + 6 * U(rng));  // some beyond the stock
    s.d = Eigen::Vector3d(4 * U(rng), 4 * U(rng), 0.5 * U(rng));
    s.axis = tilted ? Eigen::Vector3d(0.5 * U(rng), 0.5 * U(rng), 1).normalized() : Eigen::Vector3d::UnitZ();
    out.push_back(s);
  }
  return out;
}

TEST(TimePlan, ShadowRaysAreTheKernelsFootprints) {
  const removal::Box stock{Eigen::Vector3d(0.3, -0.2, 0.1), Eigen::Vector3d(40.1, 30.05, 10.2)};
  const double h = 0.25;
  const std::vector<removal::SweptTool> ball_z = random_sweeps(tool(3, 3, 30), false, 200, 1);
  const std::vector<removal::SweptTool> ball_tilted = random_sweeps(tool(3, 3, 30), true, 200, 2);
  const std::vector<removal::SweptTool> bull = random_sweeps(tool(4, 1, 30), true, 200, 3);
  // Z-map: a vertical ball moving across the rays takes the axial kernel; the others the general path.
  const removal::DexelGrid zm = removal::make_zmap(stock, h);
  const sim::RemovalWork a = sim::count_removal_work(stock, h, false, ball_z);
  EXPECT_EQ(a.sweeps, 200.0);
  EXPECT_EQ(a.axial_ball_rays, footprint_rays(zm, ball_z));
  EXPECT_EQ(a.general_rays + a.bull_nose_rays, 0.0);
  EXPECT_EQ(a.field_rays, double(zm.nu()) * zm.nv());
  EXPECT_GT(a.axial_ball_rays, 0.0);
  const sim::RemovalWork b = sim::count_removal_work(stock, h, false, ball_tilted);
  EXPECT_EQ(b.general_rays, footprint_rays(zm, ball_tilted));
  EXPECT_EQ(b.axial_ball_rays + b.bull_nose_rays, 0.0);
  // Tri-dexel: three grids; the vertical ball is axial on the Z grid only.
  const removal::TriDexel td = removal::make_tridexel(stock, h);
  const sim::RemovalWork c = sim::count_removal_work(stock, h, true, ball_z);
  EXPECT_EQ(c.axial_ball_rays, footprint_rays(td.z, ball_z));
  EXPECT_EQ(c.general_rays, footprint_rays(td.x, ball_z) + footprint_rays(td.y, ball_z));
  const sim::RemovalWork d = sim::count_removal_work(stock, h, true, bull);
  EXPECT_EQ(d.bull_nose_rays, footprint_rays(td.x, bull) + footprint_rays(td.y, bull) + footprint_rays(td.z, bull));
  EXPECT_EQ(d.field_rays,
            double(td.x.nu()) * td.x.nv() + double(td.y.nu()) * td.y.nv() + double(td.z.nu()) * td.z.nv());
  // The same shadow costs more on a bull-nose than on the general path (its bracketing and refinement), and the
  // whole run adds the field's rays and the motion.
  sim::RemovalWork g = d;
  g.general_rays = d.bull_nose_rays, g.bull_nose_rays = 0;
  EXPECT_GT(sim::predict_time(d, 0).removal_cpu_s, sim::predict_time(g, 0).removal_cpu_s);
  EXPECT_GT(sim::predict_time(d, 1.0).run_cpu_s, sim::predict_time(d, 0).removal_cpu_s + 1.0);
}

// The axial ball's tiles (the counts its cost follows): the kernel's tiles (removal/cut.cpp: 8 rows x 2^shift columns,
// shift = round(log2(R / 2h)) within [2, 5]) that its footprint (removal::footprint, the kernel's own culling)
// touches; a sweep whose lowest point stays above the stock leaves every tile settled (no open rays), and the kernel
// cuts nothing with it.
TEST(TimePlan, AxialBallTilesAreTheFootprintsTiles) {
  const removal::Box stock{Eigen::Vector3d(0.3, -0.2, 0.1), Eigen::Vector3d(40.1, 30.05, 10.2)};
  const double h = 0.25, R = 3;
  const int cols = 1 << std::clamp(static_cast<int>(std::lround(std::log2(R / (2 * h)))), 2, 5);
  const std::vector<removal::SweptTool> sweeps = random_sweeps(tool(R, R, 30), false, 200, 4);
  removal::DexelGrid zm = removal::make_zmap(stock, h);
  double tiles = 0;
  for (const removal::SweptTool& s : sweeps) {
    const removal::Footprint f = removal::footprint(zm, s);
    if (!f.empty()) tiles += double(f.i1 / cols - f.i0 / cols + 1) * double(f.j1 / 8 - f.j0 / 8 + 1);
  }
  const sim::RemovalWork a = sim::count_removal_work(stock, h, false, sweeps);
  EXPECT_EQ(a.axial_ball_tiles, tiles);
  EXPECT_GT(a.axial_ball_open_rays, 0.0);
  EXPECT_LE(a.axial_ball_open_rays, a.axial_ball_rays);
  // Above the stock: tiles tested, none open; the kernel removes nothing.
  std::vector<removal::SweptTool> above = sweeps;
  for (removal::SweptTool& s : above) s.tip0.z() = stock.hi.z() + 0.5, s.d.z() = std::abs(s.d.z());
  const sim::RemovalWork b = sim::count_removal_work(stock, h, false, above);
  EXPECT_GT(b.axial_ball_tiles, 0.0);
  EXPECT_EQ(b.axial_ball_open_rays, 0.0);
  removal::fill_box(zm, stock);
  EXPECT_EQ(removal::cut(zm, above).cuts, 0u);
  // The same pass twice, then the pass and a copy 1 mm higher: tops only go down, so a second pass opens no more than
  // the first; the higher copy finds the tiles near the first's centre lowered below its bound (a tile 2 x 2 mm at
  // the path: its top at most the centre's height less sqrt(3^2 - 1.24^2) = 2.73 mm, the copy's lowest point over it
  // the centre's height + 1 - 3 mm) and opens fewer.
  removal::SweptTool pass;
  pass.tool = tool(R, R, 30), pass.tip0 = Eigen::Vector3d(5, 15, 8), pass.d = Eigen::Vector3d(30, 0, 0);
  removal::SweptTool higher = pass;
  higher.tip0.z() += 1;
  const sim::RemovalWork once = sim::count_removal_work(stock, h, false, {pass});
  const sim::RemovalWork twice = sim::count_removal_work(stock, h, false, {pass, pass});
  const sim::RemovalWork then_higher = sim::count_removal_work(stock, h, false, {pass, higher});
  EXPECT_EQ(twice.axial_ball_tiles, 2 * once.axial_ball_tiles);
  EXPECT_LE(twice.axial_ball_open_rays, 2 * once.axial_ball_open_rays);
  EXPECT_LT(then_higher.axial_ball_open_rays - once.axial_ball_open_rays, once.axial_ball_open_rays);
}

}  // namespace
