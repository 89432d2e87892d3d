// PathPiece::speed_u on quintic pieces from the derivative coefficients set_quintic keeps (issue 21: millions of calls
// while setpoints are written) against |p_u| from jet_u, which differentiates coef term by term as speed_u did before
// (bit for bit: the same products and sums), and against a central difference of point_u (the analytic reference).
#include "motion/smooth_path.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace vmsim::motion {
namespace {

TEST(PathPieceSpeed, QuinticSpeedEqualsTheTermByTermDerivative) {
  std::mt19937_64 rng(2107);
  std::uniform_real_distribution<double> c(-50.0, 50.0), uu(0.0, 1.0);
  for (int piece = 0; piece < 200; ++piece) {
    Eigen::Matrix<double, 6, 6> coef;
    for (int i = 0; i < 6; ++i)
      for (int k = 0; k < 6; ++k) coef(i, k) = (piece % 2 == 0 && i >= 3) ? 0.0 : c(rng) / (1 + k);
    PathPiece p;
    p.set_quintic(coef);
    ASSERT_EQ(p.kind, PathPiece::Kind::Quintic);
    ASSERT_EQ(p.coef, coef);
    for (int s = 0; s < 50; ++s) {
      const double u = s < 2 ? double(s) : uu(rng);
      const double v = p.speed_u(u);
      EXPECT_EQ(v, p.jet_u(u).pu.norm()) << "piece " << piece << " u " << u;
      const double h = 1e-6;
      const double fd = (p.point_u(u + h) - p.point_u(u - h)).norm() / (2 * h);
      EXPECT_NEAR(v, fd, 1e-6 * (1 + v)) << "piece " << piece << " u " << u;
    }
  }
}

// A piece copied keeps its derivative coefficients (the smoothed path copies pieces when it splits and blends them).
TEST(PathPieceSpeed, CopiedPieceKeepsItsSpeed) {
  Eigen::Matrix<double, 6, 6> coef = Eigen::Matrix<double, 6, 6>::Zero();
  coef(0, 1) = 3.0;  // x = 3u + 4u^2: |p_u| = 3 + 8u
  coef(0, 2) = 4.0;
  PathPiece p;
  p.set_quintic(coef);
  const PathPiece q = p;
  EXPECT_DOUBLE_EQ(q.speed_u(0.5), 7.0);
  EXPECT_DOUBLE_EQ(q.speed_u(0.0), 3.0);
}

}  // namespace
}  // namespace vmsim::motion
