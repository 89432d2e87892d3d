// Issue 21, session 10: the track merge's checks inlined (merge_runs, removal/track_kernel.inc, both builds) and the
// ball kernel's intervals read by a lane permute (removal/row_cut.inc) on a finishing pattern. References: the merge's
// general loop in sweeps_from_track (one run_ok call a check, kept for turning tools; detail::merge_in_place_only) and
// sweeps_from_track_reference (the track code before issue 21), every sweep bit for bit; cut_reference (the kernel
// before issue 21), every ray bit for bit, 1 vs 2 threads and the generic vs the AVX2 build. flower_mold's own track
// against both references: tests/sim/flower_removal_test.cpp.
#include "removal/cut_internal.hpp"
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

// A 1 ms track along a wavy path: with velocities (Hermite; noisy, so that some intervals need sub-samples) or
// without (chords), or nearly straight (runs of hundreds of points and thousands of runs: several batches of runs).
PoseTrack cut10_track(int n, unsigned seed, int kind) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0, 1);
  std::uniform_real_distribution<double> u01(0, 1);
  PoseTrack t;
  t.period_s = 1e-3;
  t.tip_mm.resize(n, 3);
  if (kind == 0) t.tip_velocity_mm_per_s.resize(n, 3);
  for (int k = 0; k < n; ++k) {
    const double s = k * 1e-3;
    if (kind == 2) {
      // A circle of radius 5e4 mm: a chord within 0.05 um of it spans ~4.5 mm, ~220 points.
      t.tip_mm.row(k) << 50 + 20 * s, -30 + (20 * s) * (20 * s) / 1e5, 7 + 2e-9 * noise(rng);
      continue;
    }
    t.tip_mm.row(k) << 1 + 15 * s, 4 + 2 * std::sin(0.9 * s), 6 + 0.3 * std::cos(1.3 * s);
    if (kind == 0) {
      t.tip_velocity_mm_per_s.row(k) << 15, 1.8 * std::cos(0.9 * s), -0.39 * std::sin(1.3 * s);
      const double r = u01(rng);
      const double scale = r < 0.97 ? 1e-3 : (r < 0.995 ? 0.5 : 200.0);
      for (int c = 0; c < 3; ++c) t.tip_velocity_mm_per_s(k, c) += scale * noise(rng);
    } else {
      for (int c = 0; c < 3; ++c) t.tip_mm(k, c) += 1e-5 * noise(rng);
    }
  }
  return t;
}

bool cut10_same_sweeps(const TrackSweeps& a, const TrackSweeps& b, std::string& where) {
  if (a.sweeps.size() != b.sweeps.size()) {
    where = std::to_string(a.sweeps.size()) + " vs " + std::to_string(b.sweeps.size()) + " sweeps";
    return false;
  }
  for (std::size_t k = 0; k < a.sweeps.size(); ++k) {
    const SweptTool &x = a.sweeps[k], &y = b.sweeps[k];
    if (std::memcmp(x.tip0.data(), y.tip0.data(), 3 * sizeof(double)) != 0 ||
        std::memcmp(x.d.data(), y.d.data(), 3 * sizeof(double)) != 0 ||
        std::memcmp(x.axis.data(), y.axis.data(), 3 * sizeof(double)) != 0) {
      where = "sweep " + std::to_string(k);
      return false;
    }
  }
  if (a.points != b.points || std::memcmp(&a.error_bound_mm, &b.error_bound_mm, sizeof(double)) != 0) {
    where = "points or error bound";
    return false;
  }
  return true;
}

// sweeps_from_track with the inlined merge (in the build asked for) and with the general loop.
void cut10_expect_merges_agree(const Tool& t, const PoseTrack& tr, double tol, const std::string& what) {
  TrackOptions o;
  o.tolerance_mm = tol;
  detail::merge_in_place_only() = true;
  const TrackSweeps loop = sweeps_from_track(t, tr, o);
  detail::merge_in_place_only() = false;
  for (const bool generic : {false, true}) {
    detail::generic_kernels_only() = generic;
    const TrackSweeps fast = sweeps_from_track(t, tr, o);
    detail::generic_kernels_only() = false;
    std::string where;
    EXPECT_TRUE(cut10_same_sweeps(loop, fast, where))
        << what << ", tolerance " << tol << (generic ? ", generic" : ", AVX2 where the CPU has it") << ": " << where;
  }
}

}  // namespace

TEST(Cut10Merge, InlinedChecksGiveTheGeneralLoopsSweepsInBothBuilds) {
  const Tool t = vmsim::removal::test::tool(1.6, 1.6);
  for (const double tol : {1e-5, 1e-4, 1e-3}) {
    cut10_expect_merges_agree(t, cut10_track(30000, 9, 0), tol, "Hermite track with sub-samples");
    cut10_expect_merges_agree(t, cut10_track(30000, 4, 1), tol, "chord track");
  }
  // Runs of hundreds of points, more than a batch (512) of runs.
  const PoseTrack straight = cut10_track(200000, 2, 2);
  cut10_expect_merges_agree(t, straight, 1e-4, "nearly straight track");
  TrackOptions o;
  const TrackSweeps s = sweeps_from_track(t, straight, o);
  EXPECT_GT(s.sweeps.size(), 600u) << "fewer runs than two batches";
  EXPECT_LT(s.sweeps.size(), 200000u / 40) << "runs too short to test long ones";
  // Tracks of 1, 2 and 3 points.
  for (const int n : {1, 2, 3}) cut10_expect_merges_agree(t, cut10_track(n, 1, 1), 1e-4, std::to_string(n) + " points");
}

TEST(Cut10Merge, InlinedChecksEqualTheReferenceTrackCode) {
  const Tool t = vmsim::removal::test::tool(1.6, 1.6);
  const PoseTrack tr = cut10_track(30000, 11, 0);
  for (const double tol : {1e-4, 1e-3}) {
    TrackOptions o;
    o.tolerance_mm = tol;
    std::string where;
    EXPECT_TRUE(cut10_same_sweeps(sweeps_from_track_reference(t, tr, o), sweeps_from_track(t, tr, o), where))
        << "tolerance " << tol << ": " << where;
  }
}

// A middle tip within round-off of eps from its chord (its squared distance in the band the exact test decides): the
// run of three merges into one sweep exactly when point_segment_distance (the reference's test) says it lies within.
TEST(Cut10Merge, TipsAtTheToleranceFollowTheExactTest) {
  const Tool t = vmsim::removal::test::tool(1.6, 1.6);
  const double eps = 0.5e-4;  // tolerance 1e-4, constant axis: e_merge = tolerance / 2
  int merged = 0, split = 0;
  for (int q = -40; q <= 40; ++q) {
    PoseTrack tr;
    tr.tip_mm.resize(3, 3);
    const double off = eps * (1 + q * 1e-13);
    tr.tip_mm << 12.5, -3.25, 7.0, 12.9, -3.25 + off, 7.0, 13.3, -3.25, 7.0;
    TrackOptions o;
    o.tolerance_mm = 1e-4;
    for (const bool generic : {false, true})
      for (const bool loop : {false, true}) {
        detail::generic_kernels_only() = generic;
        detail::merge_in_place_only() = loop;
        const TrackSweeps s = sweeps_from_track(t, tr, o);
        detail::generic_kernels_only() = false;
        detail::merge_in_place_only() = false;
        const TrackSweeps r = sweeps_from_track_reference(t, tr, o);
        std::string where;
        ASSERT_TRUE(cut10_same_sweeps(r, s, where))
            << "offset step " << q << (generic ? ", generic" : "") << (loop ? ", general loop" : "") << ": " << where;
        if (!generic && !loop) (s.sweeps.size() == 1 ? merged : split) += 1;
      }
  }
  EXPECT_GT(merged, 0) << "no offset merged: the threshold was not reached";
  EXPECT_GT(split, 0) << "every offset merged: the threshold was not reached";
}

namespace {

// Finishing passes of a ball over a curved surface as a real machine's actual motion gives them: each pass in short
// consecutive sweeps (0.02-0.4 mm, slightly off the pass line), passes a stepover apart, over a box whose top a
// roughing pass left wavy.
std::vector<SweptTool> cut10_finishing(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0, 1);
  const Tool ball = vmsim::removal::test::tool(0.8, 0.8);
  std::vector<SweptTool> s;
  auto z_of = [](double x, double y) { return 6.5 + 0.6 * std::sin(0.7 * x) * std::cos(0.5 * y); };
  for (int pass = 0; pass < 2; ++pass) {
    const double step = pass == 0 ? 0.9 : 0.23, depth = pass == 0 ? 0.4 : 0.0;
    for (double y = -0.5; y < 10.5; y += step) {
      const bool back = static_cast<int>(std::lround(y / step)) % 2 == 1;
      double x = back ? 12.5 : -0.5;
      Eigen::Vector3d p(x, y, z_of(x, y) + depth);
      while (back ? x > -0.5 : x < 12.5) {
        x += (back ? -1 : 1) * (0.02 + 0.38 * u01(rng));
        const double yy = y + 2e-4 * (u01(rng) - 0.5);
        const Eigen::Vector3d q(x, yy, z_of(x, yy) + depth);
        SweptTool w;
        w.tool = ball;
        w.tip0 = p;
        w.d = q - p;
        s.push_back(w);
        p = q;
      }
    }
  }
  return s;
}

}  // namespace

TEST(Cut10Cut, FinishingPassesEqualTheReferenceThreadsAndBuildsBitForBit) {
  const std::vector<SweptTool> sweeps = cut10_finishing(23);
  const Box stock{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(12, 10, 8)};
  for (const double h : {0.05, 0.031}) {
    const auto zmap = [&] {
      DexelGrid z = make_zmap(stock, h);
      fill_box(z, stock);
      return z;
    };
    const auto [s1, sg] =
        vmsim::removal::test::expect_cut_equals_reference(zmap, sweeps, "h " + std::to_string(h));
    EXPECT_EQ(s1.bound_skipped, sg.bound_skipped);
    EXPECT_GT(s1.order_free_blocks, 0u) << "no block took the order-free kernel";
    EXPECT_GT(s1.bound_skipped, s1.ray_tests / 20) << "the ray bound settled too little to test it";
    EXPECT_GT(s1.cuts, 10000u) << "too few cuts to test anything";
  }
}
