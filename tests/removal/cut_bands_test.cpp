// Issue 21, session 8: the z-map cut of a whole job in one call that reports its progress between bands of rows
// (removal::cut with a core::Progress, as sim::cut_field calls it), and the 3-axis Hermite track's sub-steps found in
// one pass over its columns (removal/track.cpp). References: the kernel before issue 21 (cut_reference, bit for bit),
// the same sweeps cut in one call without progress and in batches of sweeps (how sim cut them before, bit for bit), an
// independent brute-force envelope of the ball sweeps (golden section over each move, tool_reference.hpp's), and
// sweeps_from_track_reference (the track's code before issue 21, bit for bit).
#include "removal/cut_internal.hpp"
#include "removal/cut_reference.hpp"
#include "removal/fields.hpp"
#include "removal/track.hpp"
#include "tests/removal/removal_test_support.hpp"
#include "tool_reference.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <cstring>
#include <random>
#include <string>

using namespace vmsim::removal;

namespace {

const Box kBandsStock{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(30, 24, 10)};

// An actual motion's kind of sweeps: passes along x of 20-60 um steps with a few um of wobble (many sweeps per ray,
// cut lowest first in chunks), 0.35 mm apart over a sloped, wavy floor, then passes along y, and random longer moves.
std::vector<SweptTool> bands_sweeps(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0, 1);
  const Tool ball = vmsim::removal::test::tool(1.6, 1.6);
  auto floor_z = [](double x, double y) { return 6 + 0.08 * x + 0.6 * std::sin(0.4 * x) * std::cos(0.3 * y); };
  std::vector<SweptTool> s;
  Eigen::Vector3d p(1, 1, floor_z(1, 1));
  auto go = [&](const Eigen::Vector3d& q) {
    SweptTool w;
    w.tool = ball;
    w.tip0 = p;
    w.d = q - p;
    if (w.d.squaredNorm() > 0) s.push_back(w);
    p = q;
  };
  for (int pass = 0; pass < 30; ++pass) {
    const double y = 1.5 + 0.35 * pass;
    for (double t = 0; t <= 1; t += 0.0015 + 0.0015 * u01(rng)) {
      const double x = pass % 2 ? 29 - 28 * t : 1 + 28 * t;
      go({x + 0.002 * (u01(rng) - 0.5), y + 0.003 * std::sin(40 * t), floor_z(x, y)});
    }
  }
  for (int pass = 0; pass < 8; ++pass) {
    const double x = 4 + 3 * pass;
    for (double t = 0; t <= 1; t += 0.004) {
      const double y = pass % 2 ? 22 - 20 * t : 2 + 20 * t;
      go({x, y, floor_z(x, y) - 0.05});
    }
  }
  for (int k = 0; k < 40; ++k) go({2 + 26 * u01(rng), 2 + 20 * u01(rng), 5.5 + 3 * u01(rng)});
  return s;
}

DexelGrid bands_zmap(double h) {
  DexelGrid z = make_zmap(kBandsStock, h);
  fill_box(z, kBandsStock);
  return z;
}

// Records every report: increasing, ending at done + the sweeps.
struct BandsProgress : vmsim::core::Progress {
  std::vector<double> seen;
  void update(double d) override { seen.push_back(d); }
};

}  // namespace

TEST(CutBands, OneCallWithProgressEqualsOneCallBatchesAndTheReferenceBitForBit) {
  const std::vector<SweptTool> sweeps = bands_sweeps(7);
  ASSERT_GT(sweeps.size(), 10000u);  // several of sim's former batches
  for (const double h : {0.1, 0.07}) {
    DexelGrid plain = bands_zmap(h), banded = bands_zmap(h), batched = bands_zmap(h), ref = bands_zmap(h);
    ASSERT_GE(plain.nv(), 8 * 30) << "fewer row blocks than the bands need to be several";
    const CutStats sp = cut(plain, sweeps);
    BandsProgress progress;
    const CutStats sb = cut(banded, sweeps, &progress, 1000.0);
    for (std::size_t b = 0; b < sweeps.size(); b += 4096)
      cut(batched,
          std::vector<SweptTool>(sweeps.begin() + static_cast<std::ptrdiff_t>(b),
                                 sweeps.begin() + static_cast<std::ptrdiff_t>(std::min(sweeps.size(), b + 4096))));
    cut_reference(ref, sweeps);
    std::string where;
    EXPECT_TRUE(vmsim::removal::test::same_grid_bits(plain, banded, where)) << "h " << h << ": one call vs with progress, " << where;
    EXPECT_TRUE(vmsim::removal::test::same_grid_bits(plain, batched, where)) << "h " << h << ": one call vs batches, " << where;
    EXPECT_TRUE(vmsim::removal::test::same_grid_bits(plain, ref, where)) << "h " << h << ": one call vs cut_reference, " << where;
    EXPECT_EQ(sp.ray_tests, sb.ray_tests);
    EXPECT_EQ(sp.cuts, sb.cuts);
    EXPECT_GT(sp.order_free_blocks, 0u) << "the order-free pass (lowest sweeps first) was not exercised";
    // Several reports, increasing, the last at done + the sweeps.
    ASSERT_GE(progress.seen.size(), 3u);
    for (std::size_t k = 1; k < progress.seen.size(); ++k) EXPECT_GT(progress.seen[k], progress.seen[k - 1]);
    EXPECT_GT(progress.seen.front(), 1000.0);
    EXPECT_DOUBLE_EQ(progress.seen.back(), 1000.0 + static_cast<double>(sweeps.size()));
  }
}

TEST(CutBands, ThreadsAndBuildsAgreeBitForBitWithProgress) {
  const std::vector<SweptTool> sweeps = bands_sweeps(11);
  const int threads = omp_get_max_threads();
  DexelGrid one = bands_zmap(0.08), two = bands_zmap(0.08), generic = bands_zmap(0.08);
  BandsProgress p1, p2, p3;
  omp_set_num_threads(1);
  cut(one, sweeps, &p1, 0);
  omp_set_num_threads(2);
  cut(two, sweeps, &p2, 0);
  vmsim::removal::detail::generic_kernels_only() = true;
  cut(generic, sweeps, &p3, 0);
  vmsim::removal::detail::generic_kernels_only() = false;
  omp_set_num_threads(threads);
  std::string where;
  EXPECT_TRUE(vmsim::removal::test::same_grid_bits(one, two, where)) << "1 vs 2 threads: " << where;
  EXPECT_TRUE(vmsim::removal::test::same_grid_bits(two, generic, where)) << "AVX2 (where the CPU has it) vs generic: " << where;
}

// The heights against an independent envelope: on each ray, the lowest point of every ball sweep over it (the ball's
// centre c(l) = c0 + l d: c_z(l) - sqrt(R^2 - r(l)^2) where the centre passes within R, r its distance across the ray;
// convex in l, minimised by golden section on the range of l where r <= R), against the stock's top.
TEST(CutBands, HeightsMatchTheBruteForceEnvelope) {
  std::vector<SweptTool> sweeps = bands_sweeps(3);
  sweeps.resize(6000);  // the first passes: enough for every kind of contact, few enough for the brute force
  DexelGrid z = bands_zmap(0.1);
  BandsProgress progress;
  cut(z, sweeps, &progress, 0);
  double worst = 0;
  int checked = 0, cut_rays = 0;
  for (int j = 0; j < z.nv(); j += 3)
    for (int i = 0; i < z.nu(); i += 5) {
      const Eigen::Vector3d o = z.ray_origin(i, j);
      double env = kBandsStock.hi.z();
      for (const SweptTool& s : sweeps) {
        const double R = s.tool.radius_mm;
        const Eigen::Vector3d c0 = s.tip0 + R * Eigen::Vector3d::UnitZ();
        // r(l)^2 = |e0 + l e|^2 across the ray (x, y): the l where it is <= R^2.
        const Eigen::Vector2d e0(c0.x() - o.x(), c0.y() - o.y()), e(s.d.x(), s.d.y());
        const double a = e.squaredNorm(), b = 2 * e0.dot(e), c = e0.squaredNorm() - R * R;
        double l0 = 0, l1 = 1;
        if (a > 1e-18) {
          const double disc = b * b - 4 * a * c;
          if (disc < 0) continue;
          l0 = std::max(0.0, (-b - std::sqrt(disc)) / (2 * a)), l1 = std::min(1.0, (-b + std::sqrt(disc)) / (2 * a));
          if (l0 > l1) continue;
        } else if (c > 0) {
          continue;
        }
        auto low = [&](double l) {
          const Eigen::Vector2d q = e0 + l * e;
          return c0.z() + l * s.d.z() - std::sqrt(std::max(0.0, R * R - q.squaredNorm()));
        };
        double fmin;
        vmsim::removal::testref::golden(low, l0, l1, fmin, 1e-12);
        env = std::min(env, fmin);
      }
      const double got = o.z() + z.top(i, j);
      worst = std::max(worst, std::abs(got - env));
      ++checked;
      cut_rays += env < kBandsStock.hi.z() - 1e-6;
    }
  EXPECT_GT(cut_rays, checked / 4) << "too few of the checked rays were cut to test anything";
  // The z-map holds floats (ulp 1e-6 mm at 10 mm) and the golden section's minimum is within ~1e-9 mm.
  EXPECT_LT(worst, 3e-6) << "largest height difference over " << checked << " rays";
}

namespace {

// A 1 ms Hermite track along a smooth curve with its exact velocities (every interval within the tolerance: no
// sub-samples), and optionally a few velocity spikes (those intervals need sub-samples).
PoseTrack bands_hermite_track(int n, bool spikes) {
  PoseTrack t;
  t.period_s = 1e-3;
  t.tip_mm.resize(n, 3);
  t.tip_velocity_mm_per_s.resize(n, 3);
  for (int k = 0; k < n; ++k) {
    const double s = k * 1e-3;  // 20 mm/s along x with a slow wave in y and z
    t.tip_mm.row(k) << 20 * s, 2 * std::sin(0.5 * s), 5 + 0.3 * std::cos(0.7 * s);
    t.tip_velocity_mm_per_s.row(k) << 20, 2 * 0.5 * std::cos(0.5 * s), -0.3 * 0.7 * std::sin(0.7 * s);
    if (spikes && k % 997 == 500) t.tip_velocity_mm_per_s(k, 1) += 3.0;
  }
  return t;
}

bool bands_same_sweep(const SweptTool& a, const SweptTool& b) {
  return std::memcmp(a.tip0.data(), b.tip0.data(), 3 * sizeof(double)) == 0 &&
         std::memcmp(a.axis.data(), b.axis.data(), 3 * sizeof(double)) == 0 &&
         std::memcmp(a.d.data(), b.d.data(), 3 * sizeof(double)) == 0;
}

}  // namespace

TEST(TrackHermiteSubsteps, SweepsEqualTheReferenceWithAndWithoutSubsamples) {
  const Tool t = vmsim::removal::test::tool(1.6, 1.6);
  for (const bool spikes : {false, true})
    for (const double tol : {1e-4, 1e-3}) {
      const PoseTrack tr = bands_hermite_track(30000, spikes);
      TrackOptions o;
      o.tolerance_mm = tol;
      const TrackSweeps a = sweeps_from_track_reference(t, tr, o), b = sweeps_from_track(t, tr, o);
      const std::string what = std::string(spikes ? "spikes" : "smooth") + ", tolerance " + std::to_string(tol);
      // The smooth track needs no sub-sample (its points are its samples); the spikes' intervals do.
      if (spikes)
        EXPECT_GT(a.points, static_cast<std::size_t>(tr.tip_mm.rows())) << what;
      else
        EXPECT_EQ(a.points, static_cast<std::size_t>(tr.tip_mm.rows())) << what;
      ASSERT_EQ(a.sweeps.size(), b.sweeps.size()) << what;
      EXPECT_LT(a.sweeps.size(), a.points / 3) << what << ": the merge merged almost nothing";
      for (std::size_t k = 0; k < a.sweeps.size(); ++k)
        ASSERT_TRUE(bands_same_sweep(a.sweeps[k], b.sweeps[k])) << what << " " << k;
      EXPECT_EQ(a.points, b.points) << what;
      EXPECT_EQ(a.error_bound_mm, b.error_bound_mm) << what;
      EXPECT_GT(a.error_bound_mm, 0) << what;
    }
}
