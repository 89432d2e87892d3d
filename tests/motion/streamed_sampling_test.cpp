// The interpolator writes its setpoints as it samples and the contour error releases a moved-in command (issue 21:
// a run's peak memory). References: the smoothed path's own points (SmoothPath::point at each setpoint's arc length,
// outside the interpolator's sampling loop), the finite differences of the positions computed here, and the contour
// error of the same inputs through the copying overload.
#include "core/machine.hpp"
#include "core/units.hpp"
#include "motion/contour.hpp"
#include "motion/interp.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

namespace {

using vmsim::core::Vec6;

Vec6 stream_xyz(double x, double y, double z) {
  Vec6 v = Vec6::Zero();
  v << x, y, z, 0, 0, 0;
  return v;
}

vmsim::core::Move stream_line(const Vec6& a, const Vec6& b, double feed_mm_per_min) {
  vmsim::core::Move m;
  m.kind = vmsim::core::MotionKind::Line;
  m.start = a;
  m.end = b;
  m.feed_mm_per_min = feed_mm_per_min;
  return m;
}

// A zigzag raster of short passes (blended corners, curvature jumps) on the Mikron.
vmsim::core::ToolPath stream_raster() {
  vmsim::core::ToolPath tp;
  tp.initial_position = stream_xyz(0, 0, 5);
  Vec6 at = tp.initial_position;
  auto to = [&](const Vec6& p, double feed) {
    tp.moves.push_back(stream_line(at, p, feed));
    at = p;
  };
  to(stream_xyz(0, 0, 0), 1200);
  for (int pass = 0; pass < 6; ++pass) {
    const double x = pass % 2 == 0 ? 20.0 : 0.0;
    to(stream_xyz(x, 0.5 * pass, -0.05 * pass), 3000);
    to(stream_xyz(x, 0.5 * (pass + 1), -0.05 * pass), 3000);
  }
  to(stream_xyz(at[0], at[1], 5), 1200);
  return tp;
}

TEST(StreamedSampling, SetpointsAreThePathsPointsAtTheirArcLengths) {
  const vmsim::core::Machine mc =
      vmsim::core::load_machine(std::string(VMSIM_SOURCE_DIR) + "/parts/machines/mikron_ucp710.toml");
  const vmsim::core::ToolPath tp = stream_raster();
  vmsim::motion::InterpOptions opt;
  const vmsim::motion::InterpResult r = vmsim::motion::interpolate(tp, mc, opt);
  const vmsim::motion::SmoothPath path = vmsim::motion::smooth_path_for(tp, mc, opt);
  const vmsim::core::Setpoints& sp = r.setpoints;
  const Eigen::Index n = sp.samples();
  ASSERT_GT(n, 100);
  ASSERT_EQ(sp.path_length_mm.size(), n);
  ASSERT_EQ(sp.path_speed_mm_per_s.size(), n);
  ASSERT_EQ(sp.move_index.size(), n);
  // First and last rows: the program's start and end exactly.
  for (Eigen::Index a = 0; a < sp.position.cols(); ++a) {
    const int pa = mc.axes[static_cast<std::size_t>(a)].program_axis;
    EXPECT_EQ(sp.position(0, a), tp.initial_position[pa]);
    EXPECT_EQ(sp.position(n - 1, a), tp.moves.back().end[pa]);
  }
  Eigen::Vector3d prev = sp.position.row(0).head<3>().transpose();
  for (Eigen::Index k = 1; k < n; ++k) {
    const Vec6 p = k + 1 < n ? path.point(sp.path_length_mm[k]) : path.end;
    for (Eigen::Index a = 0; a < sp.position.cols(); ++a)
      ASSERT_NEAR(sp.position(k, a), p[mc.axes[static_cast<std::size_t>(a)].program_axis], 1e-9) << k;
    // The path speed: the distance between consecutive points of the path over Te (the first and last rows are the
    // program's points, the same as the path's ends to within the program's rounding).
    const Eigen::Vector3d x = p.head<3>();
    if (k > 1) {
      EXPECT_NEAR(sp.path_speed_mm_per_s[k], (x - prev).norm() / sp.period_s, 1e-6) << k;
    }
    prev = x;
    EXPECT_GE(sp.move_index[k], sp.move_index[k - 1]) << k;
    EXPECT_LT(sp.move_index[k], static_cast<int>(tp.moves.size()));
  }
  EXPECT_EQ(sp.path_length_mm[n - 1], path.length);
}

TEST(StreamedSampling, MovedCommandGivesTheSameContourErrorAndIsReleased) {
  // A helix followed with a lag and noise: the normals turn everywhere, and straight stretches carry them.
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 1e-3);
  const Eigen::Index n = 4000;
  Eigen::MatrixXd cmd(n, 3), act(n + 20, 3);
  for (Eigen::Index k = 0; k < n; ++k) {
    const double t = k < n / 2 ? 0.002 * k : 0.002 * (n / 2);  // the second half: a straight line out
    const double u = k < n / 2 ? 0.0 : 0.01 * (k - n / 2);
    cmd.row(k) << 10 * std::cos(t) + u, 10 * std::sin(t), 0.001 * k;
  }
  for (Eigen::Index k = 0; k < act.rows(); ++k) {
    const Eigen::Index j = std::max<Eigen::Index>(0, std::min(k, n - 1) - 3);
    act.row(k) = cmd.row(j) + Eigen::RowVector3d(noise(rng), noise(rng), noise(rng));
  }
  const vmsim::motion::ContourError copied = vmsim::motion::contour_error(cmd, act);
  Eigen::MatrixXd moved = cmd;
  const vmsim::motion::ContourError released = vmsim::motion::contour_error(std::move(moved), act);
  EXPECT_EQ(moved.rows(), 0);
  ASSERT_EQ(copied.signed_mm.size(), released.signed_mm.size());
  for (Eigen::Index k = 0; k < copied.signed_mm.size(); ++k) {
    ASSERT_EQ(copied.signed_mm[k], released.signed_mm[k]) << k;
    ASSERT_EQ(copied.foot_segment[k], released.foot_segment[k]) << k;
  }
  EXPECT_EQ(copied.window_samples, released.window_samples);
  EXPECT_EQ(copied.mse_um2, released.mse_um2);
  // Both signs occur: the lag on the helix and the noise around the line (the normals are in use).
  EXPECT_LT(copied.signed_mm.minCoeff(), 0.0);
  EXPECT_GT(copied.signed_mm.maxCoeff(), 0.0);
}

}  // namespace
