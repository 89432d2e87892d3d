// The fast dexel kernels (removal/cut.cpp: tile bounds, the fused four-ray ball kernel, in-place cuts; fields.cpp:
// the needles' material cull) against the kernels as they were before them (removal/cut_reference.cpp, kept
// unchanged for this purpose). Reference: cut_reference's intervals. Every ray of every field must hold the very same
// floats, bit for bit, after both have cut the same sweeps from the same stock: random moves of ball, flat and
// bull-nose tools with vertical and tilted axes, rasters whose passes run over already cut material (where the tile
// bound settles most evaluations), tools buried in the stock (material above the tool's top: the kernel's scalar
// fallback and split rays), rays that already hold several intervals, and moves along a grid axis or almost along
// the rays; blocks of rows cut in program order and lowest sweep first (order-free), and with the order-free pass's
// replay of every ray. Also: the generic and AVX2 builds agree bit for bit, and 1 and 2 threads do. The comparisons
// with the reference run the fast kernels with the reference's bull-nose solver (they test the culls and the order of
// the cuts); the fast bull-nose solver is compared with it in bull_nose_test.cpp.
#include "removal/cut_internal.hpp"
#include "removal/cut_reference.hpp"
#include "removal/fields.hpp"
#include "tests/removal/removal_test_support.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>

using namespace vmsim::removal;

namespace {

const Box kEquivalenceStock{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(40, 30, 12)};

using vmsim::removal::test::tool;

SweptTool sweep(const Tool& t, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                const Eigen::Vector3d& axis = Eigen::Vector3d::UnitZ()) {
  SweptTool s;
  s.tool = t;
  s.tip0 = a;
  s.d = b - a;
  s.axis = axis.normalized();
  return s;
}

// Random moves over and into the stock: ball, flat and bull-nose in turn, short and long; 30 % of the ball and flat
// moves tilted by up to 40 deg (a tilted bull-nose is solved numerically on every ray, swept_tool.cpp: seconds per
// long move on a fine grid; cases() has a few short ones on coarse grids).
std::vector<SweptTool> random_moves(unsigned seed, int n) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(-5, 45), uy(-5, 35), uz(6, 13), ua(-0.8, 0.8), u01(0, 1);
  std::vector<SweptTool> s;
  Eigen::Vector3d p(ux(rng), uy(rng), uz(rng));
  for (int k = 0; k < n; ++k) {
    const int kind = k % 3;
    const Tool t = kind == 0 ? tool(3, 3) : kind == 1 ? tool(2.5, 0) : tool(3, 1);
    const bool tilt = u01(rng) < 0.3 && kind != 2;
    const Eigen::Vector3d axis = tilt ? Eigen::Vector3d(ua(rng), ua(rng), 1) : Eigen::Vector3d::UnitZ();
    const double len = u01(rng) < 0.5 ? 2.0 : 25.0;
    Eigen::Vector3d q = p + len * Eigen::Vector3d(u01(rng) - 0.5, u01(rng) - 0.5, 0.2 * (u01(rng) - 0.5));
    q.z() = std::clamp(q.z(), 6.0, 13.0);
    s.push_back(sweep(t, p, q, axis));
    p = q;
    if (p.x() < -5 || p.x() > 45 || p.y() < -5 || p.y() > 35) p = Eigen::Vector3d(ux(rng), uy(rng), uz(rng));
  }
  return s;
}

// A zig-zag ball raster along x over a wavy floor (3-axis), 0.3 mm apart, then a cross raster along y: every pass
// runs beside and over what the previous ones cut.
std::vector<SweptTool> raster(double R, const Eigen::Vector3d& axis = Eigen::Vector3d::UnitZ()) {
  const Tool t = tool(R, R);
  auto z = [](double x, double y) { return 8 + 1.5 * std::sin(0.3 * x) * std::cos(0.2 * y); };
  std::vector<SweptTool> s;
  for (int pass = 0; pass < 40; ++pass) {
    const double y = 2 + 0.3 * pass;
    for (int k = 0; k < 12; ++k) {
      double x0 = -2 + 4 * k, x1 = x0 + 4;
      if (pass % 2) x0 = 46 - x0, x1 = 46 - x1;
      s.push_back(sweep(t, {x0, y, z(x0, y)}, {x1, y, z(x1, y)}, axis));
    }
  }
  for (int pass = 0; pass < 20; ++pass) {
    const double x = 5 + 0.45 * pass;
    for (int k = 0; k < 8; ++k) {
      const double y0 = -2 + 4.5 * k, y1 = y0 + 4.5;
      s.push_back(sweep(t, {x, y0, z(x, y0) - 0.2}, {x, y1, z(x, y1) - 0.2}, axis));
    }
  }
  return s;
}

// An actual motion's kind of program: a raster of 40 um steps with a following error's wobble of a few um (consecutive
// sweeps much shorter than the grid's spacing, merged into chunks by the kernel), including its turns.
std::vector<SweptTool> sampled_raster() {
  const Tool t = tool(1.6, 1.6);
  std::vector<SweptTool> s;
  Eigen::Vector3d p(2, 3, 9);
  for (int pass = 0; pass < 6; ++pass) {
    for (int k = 0; k < 500; ++k) {
      const double x = pass % 2 ? 22 - 0.04 * k : 2 + 0.04 * k, y = 3 + 0.25 * pass + 0.4 * k / 500.0;
      const Eigen::Vector3d q(x, y + 0.003 * std::sin(0.7 * k),
                              9 + 0.8 * std::sin(0.2 * x) + 0.002 * std::cos(1.3 * k));
      s.push_back(sweep(t, p, q));
      p = q;
    }
  }
  return s;
}

// Short tools (body 1 mm above the corner) driven deep into the stock: material stays above the tool's top, so rays
// split; then special directions: along a grid axis, almost along the rays (ee just above the plunge threshold),
// plunges, a move along the tilted axis, a sweep from outside the stock.
std::vector<SweptTool> buried_and_special() {
  std::vector<SweptTool> s;
  const Tool ball = tool(2, 2, 5), flat = tool(2, 0, 3), bull = tool(2, 0.5, 3);
  s.push_back(sweep(ball, {5, 5, 4}, {20, 9, 3}));
  s.push_back(sweep(ball, {20, 9, 3}, {20, 20, 5}));
  s.push_back(sweep(flat, {30, 5, 6}, {10, 25, 4}));
  s.push_back(sweep(bull, {8, 22, 7}, {33, 18, 2}));
  s.push_back(sweep(ball, {12, 3, 2}, {12, 27, 2}));                 // along y
  s.push_back(sweep(ball, {3, 15, 6}, {37, 15, 6}));                 // along x
  s.push_back(sweep(tool(3, 3), {25, 12, 9}, {25 + 2e-9, 12, 5}));   // ee = 4e-18: the fast path
  s.push_back(sweep(tool(3, 3), {15, 12, 9}, {15 + 5e-10, 12, 4}));  // ee < 1e-18: a plunge
  s.push_back(sweep(tool(3, 3), {35, 25, 12}, {35, 25, 7}));         // plunge
  const Eigen::Vector3d tilted = Eigen::Vector3d(0.3, 0.2, 1).normalized(), start(28, 4, 11);
  s.push_back(sweep(tool(3, 3), start, start + 3 * tilted, tilted));  // along the tilted axis
  s.push_back(sweep(tool(3, 3), {-8, -6, 9}, {50, 40, 7}));           // across, from outside
  s.push_back(sweep(tool(3, 3), {-8, 10, 9}, {-4, 10, 7}));           // outside: cuts nothing
  return s;
}

using vmsim::removal::test::same_bits;

// Every ray of two grids holds the same floats; returns the number of rays holding material and of split rays.
std::pair<std::size_t, std::size_t> expect_same(const DexelGrid& a, const DexelGrid& b, const std::string& what) {
  std::vector<Interval> x, y;
  std::size_t full = 0, split = 0;
  for (int j = 0; j < a.nv(); ++j)
    for (int i = 0; i < a.nu(); ++i) {
      a.intervals(i, j, x);
      b.intervals(i, j, y);
      if (!same_bits(x, y)) {
        ADD_FAILURE() << what << ": ray (" << i << ", " << j << ") holds " << x.size() << " vs " << y.size()
                      << " intervals"
                      << (x.empty() || y.empty()
                              ? ""
                              : ", first [" + std::to_string(x[0].lo) + ", " + std::to_string(x[0].hi) + "] vs [" +
                                    std::to_string(y[0].lo) + ", " + std::to_string(y[0].hi) + "]");
        return {full, split};
      }
      full += !x.empty();
      split += x.size() > 1;
    }
  return {full, split};
}

// Some rays of a filled grid given several intervals (as earlier cuts leave them), so both kernels meet them.
void add_split_rays(DexelGrid& g, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> ui(0, g.nu() - 1), uj(0, g.nv() - 1);
  const float L = static_cast<float>(g.length());
  for (int k = 0; k < g.nu() * g.nv() / 50; ++k)
    g.set_intervals(ui(rng), uj(rng),
                    {Interval{0.1f * L, 0.4f * L}, Interval{0.55f * L, 0.7f * L}, Interval{0.8f * L, 0.95f * L}});
}

struct Case {
  std::string name;
  std::vector<SweptTool> sweeps;
  bool fine = true;  // also on the fine grids
};

std::vector<Case> cases() {
  std::vector<Case> c;
  c.push_back({"random moves", random_moves(3, 150)});
  c.push_back({"ball raster", raster(2.5)});
  c.push_back({"tilted ball raster", raster(2.5, Eigen::Vector3d(0.2, -0.1, 1))});
  c.push_back({"buried tools and special moves", buried_and_special()});
  c.push_back({"sampled raster", sampled_raster()});
  std::vector<SweptTool> all = random_moves(5, 30);
  for (const SweptTool& s : raster(1.5)) all.push_back(s);
  for (const SweptTool& s : buried_and_special()) all.push_back(s);
  c.push_back({"everything in one program", all});
  std::vector<SweptTool> bull = random_moves(9, 12);
  for (int k = 0; k < 3; ++k)
    bull.push_back(
        sweep(tool(3, 1), {14.0 + 5 * k, 20, 8}, {17.0 + 5 * k, 21, 8.5 - k}, Eigen::Vector3d(-0.3, 0.4 * k, 1)));
  c.push_back({"tilted bull-nose", bull, false});
  return c;
}

DexelGrid zmap_with_splits(double h, unsigned seed) {
  DexelGrid z = make_zmap(kEquivalenceStock, h);
  fill_box(z, kEquivalenceStock);
  add_split_rays(z, seed);
  return z;
}

// cut()'s three ways through a block of rows: lowest sweep first where that is exact (the default), program order
// only, and lowest first with every ray replayed in program order (the net for rays whose order matters).
enum class Way { Default, ProgramOrder, ReplayAll };

CutStats cut_way(DexelGrid& g, const std::vector<SweptTool>& s, Way way) {
  detail::program_order_only() = way == Way::ProgramOrder;
  detail::replay_every_ray() = way == Way::ReplayAll;
  const CutStats st = cut(g, s);
  detail::program_order_only() = false;
  detail::replay_every_ray() = false;
  return st;
}

// For a test's duration: the fast kernels solve a bull-nose on other rays as the reference does.
struct ReferenceBullSolver {
  ReferenceBullSolver() { detail::reference_bull_solver() = true; }
  ~ReferenceBullSolver() { detail::reference_bull_solver() = false; }
};

}  // namespace

TEST(CutEquivalence, ZmapEqualsTheReferenceKernelBitForBit) {
  const ReferenceBullSolver solver;
  for (const Case& c : cases()) {
    for (const double h : {0.2, 0.0625}) {
      if (!c.fine && h < 0.2) continue;
      DexelGrid ref = zmap_with_splits(h, 17);
      cut_reference(ref, c.sweeps);
      for (const Way way : {Way::Default, Way::ProgramOrder, Way::ReplayAll}) {
        DexelGrid fast = zmap_with_splits(h, 17);
        const CutStats s = cut_way(fast, c.sweeps, way);
        const std::string what =
            c.name + " on a z-map at " + std::to_string(h) + " mm, way " + std::to_string(static_cast<int>(way));
        const auto [full, split] = expect_same(ref, fast, what);
        EXPECT_GT(full, 0u);
        EXPECT_GT(split, 0u) << what << ": no ray with several intervals left";
        if (c.name == "ball raster") {
          // The raster is what the tile bound and the order-free blocks are for: both must act, or this test
          // exercises nothing.
          EXPECT_GT(s.tile_skipped, s.ray_tests / 10) << what;
          EXPECT_GT(s.cuts, 0u);
          if (way != Way::ProgramOrder) {
            EXPECT_GT(s.order_free_blocks, 10u) << what;
          }
          if (way == Way::ReplayAll) {
            EXPECT_GT(s.replayed, 1000u) << what;
          }
        }
        if (c.name == "sampled raster" && way != Way::ProgramOrder && h < 0.1) {
          EXPECT_GT(s.chunk_skipped, 100u) << what << ": no chunk of short sweeps settled";
        }
      }
    }
  }
}

TEST(CutEquivalence, TridexelEqualsTheReferenceKernelBitForBit) {
  const ReferenceBullSolver solver;
  for (const Case& c : cases()) {
    TriDexel fast = make_tridexel(kEquivalenceStock, 0.4), ref = make_tridexel(kEquivalenceStock, 0.4);
    DexelGrid* f[3] = {&fast.x, &fast.y, &fast.z};
    DexelGrid* r[3] = {&ref.x, &ref.y, &ref.z};
    for (int k = 0; k < 3; ++k) {
      fill_box(*f[k], kEquivalenceStock), fill_box(*r[k], kEquivalenceStock);
      cut(*f[k], c.sweeps);
      cut_reference(*r[k], c.sweeps);
      const auto [full, split] = expect_same(*r[k], *f[k], c.name + ", tri-dexel grid " + std::to_string(k));
      EXPECT_GT(full, 0u);
    }
  }
}

TEST(CutEquivalence, NeedlesEqualTheReferenceKernelBitForBit) {
  const ReferenceBullSolver solver;
  // Needles 2 mm each side of points on and in the stock, in random directions (an N-buffer on a measurement grid).
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> ux(0, 40), uy(0, 30), uz(4, 12), un(-1, 1);
  std::vector<Eigen::Vector3d> o, d;
  std::vector<double> len;
  for (int k = 0; k < 4000; ++k) {
    Eigen::Vector3d n(un(rng), un(rng), un(rng) + 1.5);
    n.normalize();
    const Eigen::Vector3d p(ux(rng), uy(rng), uz(rng));
    o.push_back(p - 2 * n), d.push_back(n), len.push_back(4);
  }
  NeedleSet initial(o, d, len);
  fill_box(initial, kEquivalenceStock);
  for (const Case& c : cases()) {
    NeedleSet fast(o, d, len), ref(o, d, len);
    fill_box(fast, kEquivalenceStock), fill_box(ref, kEquivalenceStock);
    const CutStats sf = cut(fast, c.sweeps), sr = cut_reference(ref, c.sweeps);
    std::vector<Interval> a, b, i0;
    std::size_t changed = 0;
    for (std::size_t k = 0; k < fast.size(); ++k) {
      ref.store().get(k, a);
      fast.store().get(k, b);
      initial.store().get(k, i0);
      ASSERT_TRUE(same_bits(a, b)) << c.name << ": needle " << k;
      changed += !same_bits(a, i0);
    }
    EXPECT_GT(changed, 100u) << c.name;
    EXPECT_LT(sf.ray_tests, sr.ray_tests) << c.name << ": the material cull saved no exact test";
  }
}

TEST(CutEquivalence, GenericAndAvx2BuildsAgreeBitForBit) {
  if (!__builtin_cpu_supports("avx2")) GTEST_SKIP() << "this CPU has no AVX2: only the generic build runs here";
  for (const Case& c : cases()) {
    // The two builds differ only in the ball-end kernel along the rays: the cases that exercise it.
    if (c.name == "tilted ball raster" || c.name == "tilted bull-nose") continue;
    const double h = c.fine ? 0.0625 : 0.2;
    DexelGrid a = zmap_with_splits(h, 29), b = zmap_with_splits(h, 29);
    detail::generic_kernels_only() = true;
    cut(a, c.sweeps);
    detail::generic_kernels_only() = false;
    cut(b, c.sweeps);
    expect_same(a, b, c.name + ": generic vs AVX2");
  }
}

TEST(CutEquivalence, OneAndTwoThreadsAgreeBitForBit) {
  const int before = omp_get_max_threads();
  for (const Case& c : cases()) {
    DexelGrid a = zmap_with_splits(0.1, 31), b = zmap_with_splits(0.1, 31);
    TriDexel ta = make_tridexel(kEquivalenceStock, 0.5), tb = make_tridexel(kEquivalenceStock, 0.5);
    omp_set_num_threads(1);
    cut(a, c.sweeps);
    for (DexelGrid* g : {&ta.x, &ta.y, &ta.z}) fill_box(*g, kEquivalenceStock), cut(*g, c.sweeps);
    omp_set_num_threads(2);
    cut(b, c.sweeps);
    for (DexelGrid* g : {&tb.x, &tb.y, &tb.z}) fill_box(*g, kEquivalenceStock), cut(*g, c.sweeps);
    expect_same(a, b, c.name + ": z-map, 1 vs 2 threads");
    expect_same(ta.x, tb.x, c.name + ": tri-dexel x, 1 vs 2 threads");
    expect_same(ta.y, tb.y, c.name + ": tri-dexel y, 1 vs 2 threads");
    expect_same(ta.z, tb.z, c.name + ": tri-dexel z, 1 vs 2 threads");
  }
  omp_set_num_threads(before);
}

namespace {

bool same_sweep(const SweptTool& a, const SweptTool& b) {
  return std::memcmp(a.tip0.data(), b.tip0.data(), 3 * sizeof(double)) == 0 &&
         std::memcmp(a.axis.data(), b.axis.data(), 3 * sizeof(double)) == 0 &&
         std::memcmp(a.d.data(), b.d.data(), 3 * sizeof(double)) == 0 && a.tool.radius_mm == b.tool.radius_mm &&
         a.tool.corner_radius_mm == b.tool.corner_radius_mm && a.tool.length_mm == b.tool.length_mm;
}

// A sampled motion every 1 ms: a zig-zag raster at 5-25 mm/s with rounded turns and a wobble of a few um (a drive's
// following error), optionally with tip velocities (the Hermite track) and a turning tool axis.
PoseTrack sampled_track(unsigned seed, int n, bool velocities, bool turning, bool constant_per_sample) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0, 2e-5);
  PoseTrack t;
  t.period_s = 1e-3;
  t.tip_mm.resize(n, 3);
  if (velocities) t.tip_velocity_mm_per_s.resize(n, 3);
  if (turning || constant_per_sample) t.axis_per_sample.resize(n, 3);
  double x = 0, y = 0, dir = 1;
  for (int k = 0; k < n; ++k) {
    const double v = 5 + 20 * (0.5 + 0.5 * std::sin(k * 0.001));
    x += dir * v * 1e-3;
    if (x > 30 || x < 0) dir = -dir, y += 0.3;
    const double z = 5 + 0.5 * std::sin(0.2 * x) + noise(rng);
    t.tip_mm.row(k) << x + noise(rng), y + 0.05 * std::sin(0.01 * k), z;
    if (velocities)
      t.tip_velocity_mm_per_s.row(k) << dir * v, 0.05 * 0.01 / 1e-3 * std::cos(0.01 * k),
          0.1 * dir * v * std::cos(0.2 * x);
    if (turning) t.axis_per_sample.row(k) << 0.3 * std::sin(0.0005 * k), 0.2 * std::cos(0.0007 * k), 1;
    if (constant_per_sample) t.axis_per_sample.row(k) << 0.1, -0.2, 1;
  }
  return t;
}

}  // namespace

// sweeps_from_track (the merge's distance test on squared distances, vectorised, with the exact test kept for tips near
// the tolerance) against its reference copy (removal/cut_reference.cpp, the code before): the same sweeps, points and
// error bounds, bit for bit, for chord and Hermite tracks, constant and turning axes, several tolerances.
TEST(CutEquivalence, TrackSweepsEqualTheReferenceBitForBit) {
  Tool t = tool(1.6, 1.6, 30);
  int cases = 0;
  for (const bool velocities : {false, true})
    for (const int axes : {0, 1, 2})
      for (const double tol : {1e-4, 1e-3, 1e-2}) {
        if (axes == 1 && tol < 1e-3) continue;  // a turning axis at 0.1 um: ~40 sub-steps per sample
        const PoseTrack tr = sampled_track(41 + cases, axes == 1 ? 5000 : 20000, velocities, axes == 1, axes == 2);
        TrackOptions o;
        o.tolerance_mm = tol;
        const TrackSweeps a = sweeps_from_track_reference(t, tr, o), b = sweeps_from_track(t, tr, o);
        const std::string what = "velocities " + std::to_string(velocities) + ", axes " + std::to_string(axes) +
                                 ", tolerance " + std::to_string(tol);
        ASSERT_EQ(a.sweeps.size(), b.sweeps.size()) << what;
        EXPECT_GT(a.sweeps.size(), 50u) << what;
        if (axes != 1) {
          EXPECT_LT(a.sweeps.size(), a.points * 9 / 10) << what << ": the merge merged almost nothing";
        }
        for (std::size_t k = 0; k < a.sweeps.size(); ++k)
          ASSERT_TRUE(same_sweep(a.sweeps[k], b.sweeps[k])) << what << " " << k;
        EXPECT_EQ(a.points, b.points) << what;
        EXPECT_EQ(a.error_bound_mm, b.error_bound_mm) << what;
        EXPECT_EQ(a.orientation_error_mm, b.orientation_error_mm) << what;
        ++cases;
      }
}
