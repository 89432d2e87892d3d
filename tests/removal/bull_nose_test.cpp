// Tilted flat-end and bull-nose sweeps (issue 24): the fast kernel (removal/cut.cpp with swept_tool.cpp's bracketed
// bull-nose solver) against the reference kernel (removal/cut_reference.cpp, which keeps the bull-nose solver as it
// was: nested golden sections on the distance to the swept core). Reference: cut_reference's intervals. Flat ends
// are closed forms in both, so their rays must hold the very same floats; a bull-nose's ends come from two different
// numerical solvers, each within 1e-9 mm of the true end along the ray, so every interval end must agree within
// kTol = 1e-5 mm (the float the grid stores rounds at 3.8e-6 mm at 40 mm: one float step either side, plus the
// solvers' tolerances) and every ray must hold the same number of intervals. Translating sweeps (constant tilted
// axis), turning ones (sweeps_from_track on a tool axis that swings by 20 deg), on tri-dexel grids and needles; and
// the result does not depend on the thread count.
#include "removal/cut_reference.hpp"
#include "removal/fields.hpp"
#include "removal/track.hpp"
#include "tests/removal/removal_test_support.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <cstring>
#include <random>
#include <string>

using namespace vmsim::removal;

namespace {

const Box kStock{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(30, 20, 10)};
constexpr double kTol = 1e-5;

using vmsim::removal::test::tool;

// Straight moves through the stock's top at a constant tilted axis (up to 50 deg), short and long, some deep.
std::vector<SweptTool> tilted_moves(const Tool& t, unsigned seed, int n) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(2, 28), uy(2, 18), uz(6, 10.5), ua(-1, 1), u01(0, 1);
  std::vector<SweptTool> s;
  for (int k = 0; k < n; ++k) {
    SweptTool w;
    w.tool = t;
    w.tip0 = Eigen::Vector3d(ux(rng), uy(rng), uz(rng));
    const double len = u01(rng) < 0.5 ? 1.5 : 12.0;
    w.d = len * Eigen::Vector3d(u01(rng) - 0.5, u01(rng) - 0.5, 0.3 * (u01(rng) - 0.5)).normalized();
    w.axis = Eigen::Vector3d(ua(rng), ua(rng), 1.2).normalized();
    s.push_back(w);
  }
  return s;
}

// A tool whose axis swings by 20 deg about Y while the tip runs a wavy line across the stock: a five-axis contour.
std::vector<SweptTool> turning(const Tool& t) {
  PoseTrack tr;
  const int n = 200;
  tr.tip_mm.resize(n, 3);
  tr.axis_per_sample.resize(n, 3);
  for (int k = 0; k < n; ++k) {
    const double u = k / double(n - 1), phi = (-10 + 20 * u) * M_PI / 180;
    tr.tip_mm.row(k) << 3 + 24 * u, 10 + 3 * std::sin(6 * u), 8.5 - 0.5 * std::cos(4 * u);
    tr.axis_per_sample.row(k) << std::sin(phi), 0.3 * std::sin(phi), std::cos(phi);
  }
  TrackOptions o;
  o.tolerance_mm = 0.05;
  return sweeps_from_track(t, tr, o).sweeps;
}

struct Agreement {
  std::size_t rays = 0, changed = 0;
  double worst = 0;
};

// Both grids' rays hold the same number of intervals with ends within tol (0: the same floats).
void expect_close(const DexelGrid& ref, const DexelGrid& fast, const DexelGrid& initial, double tol,
                  const std::string& what, Agreement& ag) {
  std::vector<Interval> a, b, c;
  for (int j = 0; j < ref.nv(); ++j)
    for (int i = 0; i < ref.nu(); ++i) {
      ref.intervals(i, j, a);
      fast.intervals(i, j, b);
      initial.intervals(i, j, c);
      ++ag.rays;
      ag.changed +=
          a.size() != c.size() || (!a.empty() && std::memcmp(a.data(), c.data(), a.size() * sizeof(Interval)) != 0);
      ASSERT_EQ(a.size(), b.size()) << what << ": ray (" << i << ", " << j << ")";
      for (std::size_t k = 0; k < a.size(); ++k) {
        const double e = std::max(std::abs(double(a[k].lo) - b[k].lo), std::abs(double(a[k].hi) - b[k].hi));
        ag.worst = std::max(ag.worst, e);
        ASSERT_LE(e, tol) << what << ": ray (" << i << ", " << j << ") interval " << k << ": [" << a[k].lo << ", "
                          << a[k].hi << "] vs [" << b[k].lo << ", " << b[k].hi << "]";
      }
    }
}

void compare_tridexel(const std::vector<SweptTool>& sweeps, double h, double tol, const std::string& what) {
  TriDexel fast = make_tridexel(kStock, h), ref = make_tridexel(kStock, h), init = make_tridexel(kStock, h);
  DexelGrid* f[3] = {&fast.x, &fast.y, &fast.z};
  DexelGrid* r[3] = {&ref.x, &ref.y, &ref.z};
  DexelGrid* i0[3] = {&init.x, &init.y, &init.z};
  Agreement ag;
  for (int k = 0; k < 3; ++k) {
    fill_box(*f[k], kStock), fill_box(*r[k], kStock), fill_box(*i0[k], kStock);
    cut(*f[k], sweeps);
    cut_reference(*r[k], sweeps);
    expect_close(*r[k], *f[k], *i0[k], tol, what + ", grid " + std::to_string(k), ag);
  }
  // Enough of the stock is cut for the comparison to mean something.
  EXPECT_GT(ag.changed, ag.rays / 50) << what;
  std::printf("%s: %zu of %zu rays cut, largest difference %.3g mm\n", what.c_str(), ag.changed, ag.rays, ag.worst);
}

}  // namespace

TEST(BullNose, TiltedFlatEndEqualsTheReferenceBitForBit) {
  compare_tridexel(tilted_moves(tool(2.5, 0, 25), 3, 24), 0.25, 0.0, "tilted flat end");
  compare_tridexel(turning(tool(2.5, 0, 25)), 0.25, 0.0, "turning flat end");
}

TEST(BullNose, TiltedBullNoseMatchesTheReferenceWithinTolerance) {
  compare_tridexel(tilted_moves(tool(3, 1, 25), 5, 16), 0.25, kTol, "tilted bull-nose");
  compare_tridexel(tilted_moves(tool(3, 2.5, 25), 6, 10), 0.25, kTol, "tilted bull-nose, large corner");
}

TEST(BullNose, TurningBullNoseMatchesTheReferenceWithinTolerance) {
  compare_tridexel(turning(tool(3, 1, 25)), 0.4, kTol, "turning bull-nose");
}

TEST(BullNose, NeedlesMatchTheReferenceWithinTolerance) {
  // Needles 2 mm each side of points in the stock's upper half, in random directions.
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> ux(0, 30), uy(0, 20), uz(5, 10), un(-1, 1);
  std::vector<Eigen::Vector3d> o, d;
  std::vector<double> len;
  for (int k = 0; k < 3000; ++k) {
    Eigen::Vector3d n(un(rng), un(rng), un(rng) + 1.2);
    n.normalize();
    const Eigen::Vector3d p(ux(rng), uy(rng), uz(rng));
    o.push_back(p - 2 * n), d.push_back(n), len.push_back(4);
  }
  NeedleSet fast(o, d, len), ref(o, d, len);
  fill_box(fast, kStock), fill_box(ref, kStock);
  const std::vector<SweptTool> s = tilted_moves(tool(3, 1, 25), 7, 16);
  cut(fast, s);
  cut_reference(ref, s);
  std::vector<Interval> a, b;
  std::size_t changed = 0;
  for (std::size_t k = 0; k < fast.size(); ++k) {
    ref.store().get(k, a);
    fast.store().get(k, b);
    ASSERT_EQ(a.size(), b.size()) << "needle " << k;
    for (std::size_t q = 0; q < a.size(); ++q) {
      EXPECT_NEAR(a[q].lo, b[q].lo, kTol) << "needle " << k;
      EXPECT_NEAR(a[q].hi, b[q].hi, kTol) << "needle " << k;
    }
    changed += a.size() != 1 || a[0].lo != 0.0f || a[0].hi != 4.0f;
  }
  EXPECT_GT(changed, 200u);
}

TEST(BullNose, OneAndTwoThreadsAgreeBitForBit) {
  const int before = omp_get_max_threads();
  std::vector<SweptTool> s = tilted_moves(tool(3, 1, 25), 11, 12);
  for (const SweptTool& w : turning(tool(3, 1, 25))) s.push_back(w);
  TriDexel a = make_tridexel(kStock, 0.3), b = make_tridexel(kStock, 0.3);
  DexelGrid* ga[3] = {&a.x, &a.y, &a.z};
  DexelGrid* gb[3] = {&b.x, &b.y, &b.z};
  for (int k = 0; k < 3; ++k) {
    fill_box(*ga[k], kStock), fill_box(*gb[k], kStock);
    omp_set_num_threads(1);
    cut(*ga[k], s);
    omp_set_num_threads(2);
    cut(*gb[k], s);
    Agreement ag;
    expect_close(*ga[k], *gb[k], *ga[k], 0.0, "1 vs 2 threads, grid " + std::to_string(k), ag);
  }
  omp_set_num_threads(before);
}
