// The ray-swept-tool kernel against independent references: a numerical distance to the swept volume
// (removal::distance, golden-section on the convex distance, no shared code with the closed forms), and exact
// envelopes worked out by hand for the simple cases.
#include "removal/swept_tool.hpp"
#include "tests/removal/removal_test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace vmsim::removal;

namespace {

using vmsim::removal::test::tool;

// The interval's ends lie on the volume's surface, points just inside are inside, points just outside are out.
void check_against_distance(const SweptTool& s, const Eigen::Vector3d& o, const Eigen::Vector3d& u, double tol,
                            const std::string& what) {
  double t0, t1;
  const bool hit = ray_interval(s, o, u, t0, t1);
  // Independent scan along the ray for inside points (distance <= 0).
  double first = NAN, last = NAN;
  for (int k = 0; k <= 4000; ++k) {
    const double t = -60 + 120.0 * k / 4000;
    if (distance(s, o + t * u) <= 0) {
      if (std::isnan(first)) first = t;
      last = t;
    }
  }
  if (!hit) {
    EXPECT_TRUE(std::isnan(first)) << what << ": the scan found material the kernel missed at t=" << first;
    return;
  }
  EXPECT_NEAR(distance(s, o + t0 * u), 0.0, tol) << what << " entry";
  EXPECT_NEAR(distance(s, o + t1 * u), 0.0, tol) << what << " exit";
  if (!std::isnan(first)) {
    EXPECT_LE(t0, first + 1e-9) << what;
    EXPECT_GE(t1, last - 1e-9) << what;
  }
  EXPECT_GT(distance(s, o + (t0 - 1e-4) * u), 0.0) << what;
  EXPECT_GT(distance(s, o + (t1 + 1e-4) * u), 0.0) << what;
  if (t1 - t0 > 1e-3) {
    EXPECT_LE(distance(s, o + (0.5 * (t0 + t1)) * u), 0.0) << what;
  }
}

}  // namespace

TEST(SweptTool, RandomRaysAgreeWithTheDistanceFunction) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> U(-1, 1);
  int hits = 0;
  for (int n = 0; n < 3000; ++n) {
    const int kind = n % 3;  // ball, flat, bull-nose
    SweptTool s;
    s.tool = kind == 0 ? tool(5, 5, 30) : kind == 1 ? tool(5, 0, 30) : tool(5, 1.5, 30);
    s.tip0 = Eigen::Vector3d(U(rng), U(rng), U(rng)) * 3;
    s.axis = n % 5 == 0 ? Eigen::Vector3d(U(rng), U(rng), 1 + U(rng)).normalized() : Eigen::Vector3d::UnitZ();
    s.d = Eigen::Vector3d(U(rng), U(rng), U(rng)) * 12;
    if (n % 7 == 0) s.d = 4 * s.axis;  // along the axis
    if (n % 11 == 0) s.d.setZero();    // no move
    Eigen::Vector3d u(U(rng), U(rng), U(rng));
    if (n % 4 == 0) u = Eigen::Vector3d::UnitZ();
    if (n % 4 == 1) u = Eigen::Vector3d::UnitX();
    u.normalize();
    // Aim near the volume so that most rays hit.
    const Eigen::Vector3d target =
        s.tip0 + s.d * (0.5 + 0.5 * U(rng)) + s.axis * (3 + 3 * U(rng)) + Eigen::Vector3d(U(rng), U(rng), U(rng)) * 6;
    const Eigen::Vector3d o = target - 20 * u;
    double t0, t1;
    hits += ray_interval(s, o, u, t0, t1);
    check_against_distance(s, o, u, 1e-6, "case " + std::to_string(n));
    if (HasFailure()) break;
  }
  EXPECT_GT(hits, 1500);
}

// A vertical ray through a ball-end groove: the lowest point is on the circle of the ball's section.
TEST(SweptTool, BallEndVerticalRayMatchesTheGrooveCircle) {
  SweptTool s;
  s.tool = tool(5, 5, 40);
  s.tip0 = Eigen::Vector3d(0, 0, -1);
  s.d = Eigen::Vector3d(20, 0, 0);
  for (double y = -4.99; y <= 4.99; y += 0.37) {
    double t0, t1;
    ASSERT_TRUE(ray_interval(s, Eigen::Vector3d(10, y, -20), Eigen::Vector3d::UnitZ(), t0, t1));
    const double z = -20 + t0, expected = -1 + 5 - std::sqrt(25 - y * y);
    EXPECT_NEAR(z, expected, 1e-12) << "y=" << y;
  }
}

// An inclined straight ball-end move: along a vertical line the lowest point of the capsule, found here by
// bisection on the exact point-to-segment distance (the capsule's definition).
TEST(SweptTool, InclinedBallMoveEqualsTheCapsuleEnvelope) {
  SweptTool s;
  s.tool = tool(5, 5, 40);
  s.tip0 = Eigen::Vector3d(0, 0, 0);
  s.d = Eigen::Vector3d(30, 10, -6);
  const Eigen::Vector3d c0 = s.tip0 + Eigen::Vector3d(0, 0, 5), c1 = c0 + s.d;
  auto seg_dist = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d d = c1 - c0;
    const double t = std::clamp((p - c0).dot(d) / d.squaredNorm(), 0.0, 1.0);
    return (c0 + t * d - p).norm();
  };
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> X(-6, 36), Y(-6, 16);
  int checked = 0;
  for (int n = 0; n < 2000; ++n) {
    const double x = X(rng), y = Y(rng);
    double t0, t1;
    const bool hit = ray_interval(s, Eigen::Vector3d(x, y, -50), Eigen::Vector3d::UnitZ(), t0, t1);
    // Lowest z with distance <= R: scan down from the closest approach, then bisect.
    double zlo = -20, zhi = 10, best = 1e9, zb = 0;
    for (int k = 0; k <= 3000; ++k) {
      const double z = zlo + (zhi - zlo) * k / 3000;
      const double dd = seg_dist(Eigen::Vector3d(x, y, z));
      if (dd < best) best = dd, zb = z;
    }
    if (best > 5) {
      EXPECT_FALSE(hit && t1 - t0 > 1e-6) << x << " " << y;
      continue;
    }
    ASSERT_TRUE(hit) << x << " " << y;
    double a = zlo, b = zb;  // a outside (below), b inside
    for (int it = 0; it < 200; ++it) {
      const double m = 0.5 * (a + b);
      (seg_dist(Eigen::Vector3d(x, y, m)) <= 5 ? b : a) = m;
    }
    EXPECT_NEAR(-50 + t0, b, 1e-9) << x << " " << y;
    ++checked;
  }
  EXPECT_GT(checked, 800);
}

// A flat end leaves an exact floor and a cylindrical wall.
TEST(SweptTool, FlatEndFloorAndWall) {
  SweptTool s;
  s.tool = tool(5, 0, 40);
  s.tip0 = Eigen::Vector3d(0, 0, -2);
  s.d = Eigen::Vector3d(20, 0, 0);
  double t0, t1;
  // Vertical rays: the floor at z = -2 everywhere within the slot's width.
  for (double y = -4.999; y < 5; y += 0.5) {
    ASSERT_TRUE(ray_interval(s, Eigen::Vector3d(7, y, -10), Eigen::Vector3d::UnitZ(), t0, t1));
    EXPECT_NEAR(-10 + t0, -2.0, 1e-12);
  }
  EXPECT_FALSE(ray_interval(s, Eigen::Vector3d(7, 5.001, -10), Eigen::Vector3d::UnitZ(), t0, t1));
  // Horizontal rays along Y at the slot's middle: the walls at y = +-5.
  ASSERT_TRUE(ray_interval(s, Eigen::Vector3d(7, -20, 0), Eigen::Vector3d::UnitY(), t0, t1));
  EXPECT_NEAR(-20 + t0, -5.0, 1e-12);
  EXPECT_NEAR(-20 + t1, 5.0, 1e-12);
  // Around the end of the move the wall is the cylinder x^2 + y^2 = 25 about the final position (20, 0).
  ASSERT_TRUE(ray_interval(s, Eigen::Vector3d(-20, 3, 0), Eigen::Vector3d::UnitX(), t0, t1));
  EXPECT_NEAR(-20 + t1, 20 + 4.0, 1e-12);
  EXPECT_NEAR(-20 + t0, -4.0, 1e-12);
}
