// The arc-length inversion of quintic pieces (PathPiece::u_at, s_at, SmoothPath::point with a cursor), whose speeds are
// now evaluated five at a time (issue 21), against the path it replaced: the same Newton steps written here with one
// PathPiece::speed_u call per point, as motion/smooth_path.cpp had them. Bit for bit on random pieces, and the
// inversion against the arc length itself (u_at(s_at(u)) returns u: the analytic reference).
#include "motion/smooth_path.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>

namespace vmsim::motion {
namespace {

// The 4-point Gauss-Legendre rule on [-1, 1] (Abramowitz & Stegun table 25.4), as smooth_path.cpp writes its nodes.
constexpr std::array<double, 2> kNewtonRefX = {0.3399810435848563, 0.8611363115940526};
constexpr std::array<double, 2> kNewtonRefW = {0.6521451548625461, 0.3478548451374538};

double newton_ref_integrate(const PathPiece& p, double u0, double u1) {
  const double half = 0.5 * (u1 - u0), mid = 0.5 * (u0 + u1);
  double sum = 0.0;
  for (int i = 0; i < 2; ++i)
    sum += kNewtonRefW[i] * (p.speed_u(mid - half * kNewtonRefX[i]) + p.speed_u(mid + half * kNewtonRefX[i]));
  return sum * half;
}

double newton_ref_s_at(const PathPiece& p, double u) {
  const double span = p.u_end - p.u_begin;
  const double x = std::clamp((u - p.u_begin) / span, 0.0, 1.0) * PathPiece::kTable;
  const int k = std::min(static_cast<int>(x), PathPiece::kTable - 1);
  const double uk = p.u_begin + span * k / PathPiece::kTable;
  return p.cum[k] + newton_ref_integrate(p, uk, u);
}

double newton_ref_u_at(const PathPiece& p, double s_local) {
  const double span = p.u_end - p.u_begin;
  if (s_local <= 0) return p.u_begin;
  if (s_local >= p.length) return p.u_end;
  const int k = static_cast<int>(std::upper_bound(p.cum.begin(), p.cum.end(), s_local) - p.cum.begin()) - 1;
  const int kk = std::clamp(k, 0, PathPiece::kTable - 1);
  const double ua = p.u_begin + span * kk / PathPiece::kTable, ub = p.u_begin + span * (kk + 1) / PathPiece::kTable;
  double u = ua + (ub - ua) * (s_local - p.cum[kk]) / std::max(p.cum[kk + 1] - p.cum[kk], 1e-300);
  for (int it = 0; it < 8; ++it) {
    const double f = p.cum[kk] + newton_ref_integrate(p, ua, u) - s_local;
    const double step = f / p.speed_u(u);
    u = std::clamp(u - step, ua, ub);
    if (std::abs(step) < 1e-14 * (ub - ua)) break;
  }
  return u;
}

// SmoothPath::point(s, cursor) on one non-uniform piece starting at s = 0, as it was.
struct NewtonRefCursor {
  double u = -1.0, s_local = 0.0;
};
core::Vec6 newton_ref_point(const PathPiece& p, double sl, NewtonRefCursor& c) {
  if (c.u < 0 || sl < c.s_local) {
    c.u = newton_ref_u_at(p, sl);
    c.s_local = sl;
    return p.point_u(c.u);
  }
  const double u0 = c.u, s0 = c.s_local;
  double u = u0 + (sl - s0) / p.speed_u(u0);
  if (!(std::abs(u - u0) <= (p.u_end - p.u_begin) / PathPiece::kTable)) {
    c.u = newton_ref_u_at(p, sl);
    c.s_local = sl;
    return p.point_u(c.u);
  }
  for (int it = 0; it < 4; ++it) {
    const double f = s0 + newton_ref_integrate(p, u0, u) - sl;
    const double step = f / p.speed_u(u);
    u = std::clamp(u - step, p.u_begin, p.u_end);
    if (std::abs(step) < 1e-14 * (p.u_end - p.u_begin)) break;
  }
  c.u = u;
  c.s_local = sl;
  return p.point_u(u);
}

// A regular random quintic (the linear term dominates, so |p_u| stays away from zero as a blend's does).
PathPiece newton_ref_piece(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> c(-1.0, 1.0);
  Eigen::Matrix<double, 6, 6> coef = Eigen::Matrix<double, 6, 6>::Zero();
  for (int i = 0; i < 6; ++i) {
    coef(i, 0) = 100 * c(rng);
    coef(i, 1) = (i < 3 ? 5.0 : 0.5) * c(rng) + (i == 0 ? 8.0 : 0.0);
    for (int k = 2; k < 6; ++k) coef(i, k) = (i < 3 ? 1.5 : 0.1) * c(rng) / k;
  }
  PathPiece p;
  p.set_quintic(coef);
  p.uniform = false;
  p.u_begin = 0.1 * std::abs(c(rng));
  p.u_end = 1.0 - 0.1 * std::abs(c(rng));
  p.finalize();
  return p;
}

TEST(ArcLengthNewton, QuinticInversionIsBitForBitThePerPointSpeedPath) {
  std::mt19937_64 rng(2126);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int trial = 0; trial < 60; ++trial) {
    const PathPiece p = newton_ref_piece(rng);
    ASSERT_GT(p.length, 0.0);
    // The table: each entry the 4-point rule over 1/64 of the range, as before.
    double cum = 0.0;
    for (int k = 0; k < PathPiece::kTable; ++k) {
      const double span = p.u_end - p.u_begin;
      cum += newton_ref_integrate(p, p.u_begin + span * k / PathPiece::kTable,
                                  p.u_begin + span * (k + 1) / PathPiece::kTable);
      ASSERT_EQ(p.cum[k + 1], cum) << "trial " << trial << " entry " << k + 1;
    }
    for (int q = 0; q < 200; ++q) {
      const double u = p.u_begin + (p.u_end - p.u_begin) * unit(rng);
      const double s = p.length * unit(rng);
      ASSERT_EQ(p.s_at(u), newton_ref_s_at(p, u)) << "trial " << trial << " u " << u;
      ASSERT_EQ(p.u_at(s), newton_ref_u_at(p, s)) << "trial " << trial << " s " << s;
      // The inversion itself: back to the same u within a few ulp of the parameter range.
      EXPECT_NEAR(p.u_at(p.s_at(u)), u, 1e-12) << "trial " << trial;
    }
    // Setpoint-like queries: increasing arc lengths in steps of a few thousandths of the piece, with a step back now
    // and then (a new pass), through the cursor.
    SmoothPath sp;
    sp.pieces.push_back(p);
    sp.pieces.back().s_begin = 0.0;
    sp.length = p.length;
    sp.start = p.point_u(p.u_begin);
    sp.end = p.point_u(p.u_end);
    SmoothPath::Cursor cursor;
    NewtonRefCursor ref;
    double s = 1e-9;
    for (int k = 0; s < p.length; ++k) {
      const core::Vec6 a = sp.point(s, cursor), b = newton_ref_point(sp.pieces.front(), s, ref);
      for (int i = 0; i < 6; ++i) ASSERT_EQ(a[i], b[i]) << "trial " << trial << " query " << k << " axis " << i;
      ASSERT_EQ(cursor.u, ref.u);
      s += p.length * (k % 97 == 96 ? -0.01 : 0.004 * unit(rng));
      s = std::max(s, 1e-9);
    }
  }
}

}  // namespace
}  // namespace vmsim::motion
