// Issue 21, session 9: the z-map kernel's shadow columns of a block's rows computed side by side (row_columns, both
// builds) and the Hermite track's per-interval bow vectorised (hermite_bow, both builds). References: the scalar
// functions they replace, written independently of them (axial_ball_columns in removal/cut_internal.hpp, still the
// replay's; the Eigen expressions of the track code, here), bit for bit; sweeps_from_track_reference (the track code
// before issue 21) and cut_reference (the kernel before issue 21), every sweep and every ray bit for bit; 1 vs 2
// threads and the generic vs the AVX2 build. (The heights against a brute-force envelope: cut_bands_test.cpp.)
#include "removal/cut_internal.hpp"
#include "removal/cut_reference.hpp"
#include "removal/fields.hpp"
#include "removal/row_bounds.hpp"
#include "removal/track.hpp"
#include "tests/removal/removal_test_support.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>

using namespace vmsim::removal;

namespace {

const Box kCut9Stock{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(12, 10, 8)};

DexelGrid cut9_zmap(double h) {
  DexelGrid z = make_zmap(kCut9Stock, h);
  fill_box(z, kCut9Stock);
  return z;
}

// Ball sweeps of every kind the shadow's cases tell apart: moves across the rows and along them, exactly along u or v
// (ev or eu zero), nearly so (1e-16 .. 1e-13: either side of the 1e-15 switch), long and short, rising and falling,
// some starting outside the grid.
std::vector<SweptTool> cut9_sweeps(unsigned seed, int count) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0, 1);
  const Tool ball = vmsim::removal::test::tool(0.8, 0.8);
  std::vector<SweptTool> s;
  for (int k = 0; k < count; ++k) {
    SweptTool w;
    w.tool = ball;
    w.tip0 = Eigen::Vector3d(-1 + 14 * u01(rng), -1 + 12 * u01(rng), 5 + 3.5 * u01(rng));
    const double len = u01(rng) < 0.7 ? 0.01 + 0.1 * u01(rng) : 0.5 + 4 * u01(rng);
    const double ang = 2 * M_PI * u01(rng);
    Eigen::Vector3d d(len * std::cos(ang), len * std::sin(ang), 0.3 * len * (u01(rng) - 0.5));
    switch (k % 7) {
      case 1:
        d.y() = 0;
        break;
      case 2:
        d.x() = 0;
        break;
      case 3:
        d.y() = (u01(rng) < 0.5 ? 1e-16 : 3e-15) * (u01(rng) - 0.5);
        break;
      case 4:
        d.x() = (u01(rng) < 0.5 ? 1e-16 : 3e-15) * (u01(rng) - 0.5);
        break;
      default:
        break;
    }
    w.d = d;
    s.push_back(w);
  }
  return s;
}

}  // namespace

TEST(Cut9RowColumns, BothBuildsEqualTheScalarShadowBitForBit) {
  const DexelGrid z = cut9_zmap(0.05);
  const bool avx2 = __builtin_cpu_supports("avx2");
  long rows = 0, nonempty = 0;
  for (const SweptTool& s : cut9_sweeps(5, 4000)) {
    detail::AxialBall b;
    if (!detail::axial_ball(z, s, b)) continue;
    for (int i0 : {0, 37}) {
      const int i1 = i0 == 0 ? z.nu() - 1 : 150;
      const BallColumns bc{b.eu, b.ev, b.ee, b.cu, z.du(), b.R * b.el, i0, i1};
      // Every row near the sweep, in blocks of up to 8 as cut() takes them.
      const int jc = static_cast<int>(std::floor(b.cv / z.dv()));
      for (int j0 = std::max(0, jc - 40); j0 < std::min(z.nv(), jc + 40); j0 += 8) {
        const int n = std::min(8, z.nv() - j0);
        double qv[8];
        for (int k = 0; k < n; ++k) qv[k] = z.v_of(j0 + k) - b.cv;
        int ga[8], gb[8], va[8], vb[8];
        row_columns_generic(bc, qv, n, ga, gb);
        if (avx2) row_columns_avx2(bc, qv, n, va, vb);
        for (int k = 0; k < n; ++k) {
          int a = 0, e = -1;
          const bool hit = detail::axial_ball_columns(z, b, j0 + k, i0, i1, a, e);
          ++rows;
          nonempty += hit;
          ASSERT_EQ(hit, ga[k] <= gb[k]) << "row " << j0 + k;
          if (hit) {
            ASSERT_EQ(a, ga[k]) << "row " << j0 + k;
            ASSERT_EQ(e, gb[k]) << "row " << j0 + k;
          }
          if (avx2) {
            ASSERT_EQ(hit, va[k] <= vb[k]) << "AVX2, row " << j0 + k;
            if (hit) {
              ASSERT_EQ(a, va[k]) << "AVX2, row " << j0 + k;
              ASSERT_EQ(e, vb[k]) << "AVX2, row " << j0 + k;
            }
          }
        }
      }
    }
  }
  EXPECT_GT(nonempty, rows / 10) << "too few rows in the sweeps' shadows to test anything";
  EXPECT_GT(rows - nonempty, rows / 10) << "too few rows outside the shadows";
}

namespace {

// The track code's expressions (removal/track.cpp before session 9, Eigen on 3-vectors): |p''|max of interval k.
double cut9_bow_eigen(const PoseTrack& t, Eigen::Index k) {
  const Eigen::Vector3d p0 = t.tip_mm.row(k).transpose(), p1 = t.tip_mm.row(k + 1).transpose();
  const Eigen::Vector3d m0 = t.tip_velocity_mm_per_s.row(k).transpose() * t.period_s;
  const Eigen::Vector3d m1 = t.tip_velocity_mm_per_s.row(k + 1).transpose() * t.period_s;
  const double s0 = (6 * (p1 - p0) - 4 * m0 - 2 * m1).squaredNorm();
  const double s1 = (-6 * (p1 - p0) + 2 * m0 + 4 * m1).squaredNorm();
  return std::sqrt(std::max(s0, s1));
}

// A 1 ms Hermite track along a wavy path with noisy velocities (the drives' actual motion: intervals within the
// tolerance and, where the noise is large, intervals that need 2 to 1000 sub-samples).
PoseTrack cut9_track(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0, 1);
  std::uniform_real_distribution<double> u01(0, 1);
  PoseTrack t;
  t.period_s = 1e-3;
  t.tip_mm.resize(n, 3);
  t.tip_velocity_mm_per_s.resize(n, 3);
  for (int k = 0; k < n; ++k) {
    const double s = k * 1e-3;
    t.tip_mm.row(k) << 1 + 15 * s, 4 + 2 * std::sin(0.9 * s), 6 + 0.3 * std::cos(1.3 * s);
    t.tip_velocity_mm_per_s.row(k) << 15, 1.8 * std::cos(0.9 * s), -0.39 * std::sin(1.3 * s);
    const double r = u01(rng);
    const double scale = r < 0.97 ? 1e-3 : (r < 0.995 ? 0.5 : 200.0);
    for (int c = 0; c < 3; ++c) t.tip_velocity_mm_per_s(k, c) += scale * noise(rng);
  }
  return t;
}

}  // namespace

TEST(Cut9HermiteBow, BothBuildsEqualTheEigenExpressionsBitForBit) {
  const PoseTrack t = cut9_track(5000, 3);
  const std::size_t n = static_cast<std::size_t>(t.tip_mm.rows()) - 1;
  const double* tx = t.tip_mm.col(0).data();
  const double* ty = t.tip_mm.col(1).data();
  const double* tz = t.tip_mm.col(2).data();
  const double* vx = t.tip_velocity_mm_per_s.col(0).data();
  const double* vy = t.tip_velocity_mm_per_s.col(1).data();
  const double* vz = t.tip_velocity_mm_per_s.col(2).data();
  const double eps = 0.5e-4;
  std::vector<double> ga(n), gr(n), va(n), vr(n);
  // Blocks that do not start at 0, as the caller's.
  for (std::size_t k0 = 0; k0 < n; k0 += 333) {
    const std::size_t k1 = std::min(n, k0 + 333);
    hermite_bow_generic(tx, ty, tz, vx, vy, vz, k0, k1, t.period_s, eps, ga.data() + k0, gr.data() + k0);
    if (__builtin_cpu_supports("avx2"))
      hermite_bow_avx2(tx, ty, tz, vx, vy, vz, k0, k1, t.period_s, eps, va.data() + k0, vr.data() + k0);
  }
  int many = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const double a = cut9_bow_eigen(t, static_cast<Eigen::Index>(k)), r = std::sqrt(a / (8 * eps));
    ASSERT_EQ(std::memcmp(&a, &ga[k], sizeof a), 0) << "interval " << k;
    ASSERT_EQ(std::memcmp(&r, &gr[k], sizeof r), 0) << "interval " << k;
    if (__builtin_cpu_supports("avx2")) {
      ASSERT_EQ(std::memcmp(&a, &va[k], sizeof a), 0) << "AVX2, interval " << k;
      ASSERT_EQ(std::memcmp(&r, &vr[k], sizeof r), 0) << "AVX2, interval " << k;
    }
    many += r > 1;
  }
  EXPECT_GT(many, 20) << "too few intervals needing sub-samples";
}

TEST(Cut9HermiteBow, SweepsEqualTheReferenceInBothBuilds) {
  const Tool t = vmsim::removal::test::tool(1.6, 1.6);
  const PoseTrack tr = cut9_track(40000, 9);
  for (const bool generic : {false, true})
    for (const double tol : {1e-4, 1e-3}) {
      TrackOptions o;
      o.tolerance_mm = tol;
      detail::generic_kernels_only() = generic;
      const TrackSweeps b = sweeps_from_track(t, tr, o);
      detail::generic_kernels_only() = false;
      const TrackSweeps a = sweeps_from_track_reference(t, tr, o);
      ASSERT_EQ(a.sweeps.size(), b.sweeps.size()) << "tolerance " << tol << (generic ? ", generic" : "");
      for (std::size_t k = 0; k < a.sweeps.size(); ++k) {
        const SweptTool &x = a.sweeps[k], &y = b.sweeps[k];
        ASSERT_TRUE(std::memcmp(x.tip0.data(), y.tip0.data(), 3 * sizeof(double)) == 0 &&
                    std::memcmp(x.d.data(), y.d.data(), 3 * sizeof(double)) == 0 &&
                    std::memcmp(x.axis.data(), y.axis.data(), 3 * sizeof(double)) == 0)
            << "sweep " << k << ", tolerance " << tol << (generic ? ", generic" : "");
      }
      EXPECT_GT(b.points, static_cast<std::size_t>(tr.tip_mm.rows())) << "no interval was sub-sampled";
      EXPECT_EQ(a.points, b.points);
      EXPECT_EQ(a.error_bound_mm, b.error_bound_mm);
    }
}

TEST(Cut9Cut, RandomSweepsEqualTheReferenceThreadsAndBuildsBitForBit) {
  const std::vector<SweptTool> sweeps = cut9_sweeps(17, 3000);
  for (const double h : {0.05, 0.037}) {
    const auto [s1, sg] = vmsim::removal::test::expect_cut_equals_reference([&] { return cut9_zmap(h); }, sweeps,
                                                                            "h " + std::to_string(h));
    EXPECT_EQ(s1.ray_tests, sg.ray_tests);
    EXPECT_GT(s1.cuts, 10000u) << "too few cuts to test anything";
  }
}
