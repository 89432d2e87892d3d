// vmsim compensate's figures (sim::contour_figures): the contour error of a motion against the planned tip path on
// the cutting moves only, and the tool axis' orientation error at the foot point. Reference: a straight command line
// and an actual path offset from it by known distances (max, mean and rms by hand), rapid rows left out by the
// program's own move kinds, and a tool axis tilted by a known angle.
#include "core/setpoints.hpp"
#include "core/toolpath.hpp"
#include "sim/compensate.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace vmsim;

TEST(CompensateFigures, CuttingMovesOnlyAndTheToolAxisAngleAtTheFoot) {
  // 201 setpoints along X (0.1 mm apart): rows 0-49 belong to a rapid (move 0), rows 50-200 to a feed move (move 1).
  const Eigen::Index ns = 201, rows = ns + 20;  // 20 settling rows take the last move
  core::ToolPath program;
  program.moves.resize(2);
  program.moves[0].rapid = true;
  program.moves[1].rapid = false;
  core::Setpoints sp;
  sp.period_s = 1e-3;
  sp.position = Eigen::MatrixXd::Zero(ns, 3);
  sp.move_index.resize(ns);
  Eigen::MatrixXd cmd(ns, 3), act(rows, 3), cmd_axis(ns, 3), act_axis(rows, 3);
  for (Eigen::Index k = 0; k < ns; ++k) {
    cmd.row(k) << 0.1 * static_cast<double>(k), 0.0, 0.0;
    sp.move_index[k] = k < 50 ? 0 : 1;
    cmd_axis.row(k) << 0, 0, 1;
  }
  // The actual point: 5 um to the side on the feed rows (3 um on every other of them), 1 mm on the rapid's; the tool
  // axis tilted by 0.01 rad about X on the feed rows, 0.2 rad on the rapid's.
  double sum = 0, sum2 = 0;
  int n = 0;
  for (Eigen::Index k = 0; k < rows; ++k) {
    const Eigen::Index c = std::min(k, ns - 1);
    const bool feed = c >= 50;
    const double d = feed ? (k % 2 ? 0.003 : 0.005) : 1.0, tilt = feed ? 0.01 : 0.2;
    act.row(k) << cmd(c, 0), d, 0.0;
    act_axis.row(k) << 0.0, std::sin(tilt), std::cos(tilt);
    if (feed) sum += d, sum2 += d * d, ++n;
  }
  const sim::ContourFigures f = sim::contour_figures(cmd, act, sp, program, &cmd_axis, &act_axis);
  EXPECT_EQ(f.samples, n);
  EXPECT_NEAR(f.max_mm, 0.005, 1e-12);
  EXPECT_NEAR(f.mean_mm, sum / n, 1e-12);
  EXPECT_NEAR(f.rms_mm, std::sqrt(sum2 / n), 1e-12);
  EXPECT_TRUE(f.orientation);
  EXPECT_NEAR(f.orientation_max_rad, 0.01, 1e-12);
  EXPECT_NEAR(f.orientation_mean_rad, 0.01, 1e-12);
  ASSERT_EQ(f.ce.signed_mm.size(), rows);  // every row is kept for the plots, the rapid's included
  EXPECT_NEAR(std::abs(f.ce.signed_mm[10]), 1.0, 1e-12);
  // Without tool axes: the tip only.
  const sim::ContourFigures t = sim::contour_figures(cmd, act, sp, program);
  EXPECT_FALSE(t.orientation);
  EXPECT_EQ(t.max_mm, f.max_mm);
  EXPECT_EQ(t.orientation_max_rad, 0.0);
}
