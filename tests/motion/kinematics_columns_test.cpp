// Kinematics::forward_rows and tip_velocity_rows' column paths (issue 21, session 9: runs of rows whose rotary joints
// stand still go column by column) against the per-row forward() and tip_velocity() (the reference: the single-pose
// functions, unchanged), bit for bit, on random rows whose rotary axes hold for long runs (longer than a chunk of
// 256 rows, shorter than the 16 rows a column run needs, and in between) at +0, -0 or a random angle, with exact
// zeros, negative zeros and a few infinities among the linear axes and tool length offsets, in blocks of 1, 7 and
// all rows. The Cartesian machine's rows are columns copied (and Z - tlo): the same test.
#include "core/machine.hpp"
#include "motion/kinematics.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace vmsim::motion {
namespace {

namespace fs = std::filesystem;

const fs::path kColMachines = fs::path(VMSIM_SOURCE_DIR) / "parts" / "machines";

bool col_same_bits(const Eigen::Vector3d& a, const Eigen::MatrixXd& m, Eigen::Index row) {
  const Eigen::Vector3d b = m.row(row).transpose();
  return std::memcmp(a.data(), b.data(), 3 * sizeof(double)) == 0;
}

// The Mikron with its rotary joints on the tool side (the tool chain turns: tip_velocity_rows keeps its row path) and
// a linear joint on the workpiece side.
core::Machine col_head_head_machine() {
  core::Machine m = core::load_machine(kColMachines / "mikron_ucp710.toml");
  core::KinematicChain& ch = *m.chain;
  std::vector<core::ChainJoint> rotary = ch.workpiece;
  rotary[0].point_mm = Eigen::Vector3d(3, -4, 120);
  rotary[1].point_mm = Eigen::Vector3d(-2, 5, 80);
  ch.workpiece = {ch.tool[0]};
  ch.workpiece[0].direction = -ch.workpiece[0].direction;
  ch.tool = {ch.tool[1], ch.tool[2], rotary[0], rotary[1]};
  ch.gauge_point_mm = Eigen::Vector3d(0.5, -0.25, 40);
  ch.workpiece_origin_mm = Eigen::Vector3d(7, -3, 2);
  return m;
}

// The Mikron with a workpiece origin and gauge point off zero, the tool direction tilted and one linear joint on the
// workpiece side (every term of the column sums counts).
core::Machine col_offset_machine() {
  core::Machine m = core::load_machine(kColMachines / "mikron_ucp710.toml");
  core::KinematicChain& ch = *m.chain;
  ch.workpiece_origin_mm = Eigen::Vector3d(1.5, -2.25, 0.125);
  ch.gauge_point_mm = Eigen::Vector3d(-0.5, 0.75, 30);
  ch.tool_direction = Eigen::Vector3d(0.1, -0.2, 1);
  ch.workpiece.insert(ch.workpiece.begin(), ch.tool[1]);
  ch.workpiece[0].direction = Eigen::Vector3d(0.3, -1, 0.2);
  ch.tool.erase(ch.tool.begin() + 1);
  return m;
}

struct ColInput {
  Eigen::MatrixXd q, qd;
  Eigen::VectorXd tlo;
};

// A value of a linear axis: mostly random, sometimes +0, -0 or (when `infinite`) an infinity.
double col_linear_value(std::mt19937_64& rng, double scale, bool infinite) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> pick(0, 199);
  const int p = pick(rng);
  if (p < 12) return 0.0;
  if (p < 24) return -0.0;
  if (infinite && p == 24) return std::numeric_limits<double>::infinity();
  return scale * u(rng);
}

ColInput col_random_rows(const core::Machine& m, Eigen::Index n, std::mt19937_64& rng, bool infinite) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> run(1, 600), pick(0, 3);
  const auto axes = static_cast<Eigen::Index>(m.axes.size());
  ColInput in{Eigen::MatrixXd(n, axes), Eigen::MatrixXd(n, axes), Eigen::VectorXd(n)};
  // The rotary axes change together (a run of rows at one pose), as a three-axis stretch of a program holds them.
  std::vector<double> held(static_cast<std::size_t>(axes), 0.0);
  int left = 0;
  for (Eigen::Index k = 0; k < n; ++k) {
    if (left-- <= 0) {
      left = run(rng);
      for (auto& h : held) {
        const int p = pick(rng);
        h = p == 0 || p == 3 ? 0.0 : p == 1 ? -0.0 : 3 * u(rng);
      }
    }
    for (Eigen::Index a = 0; a < axes; ++a) {
      const bool rotary = m.axes[static_cast<std::size_t>(a)].kind == core::AxisKind::Rotary;
      in.q(k, a) = rotary ? held[static_cast<std::size_t>(a)] : col_linear_value(rng, 300, infinite);
      in.qd(k, a) = col_linear_value(rng, rotary ? 2 : 500, infinite);
    }
    in.tlo[k] = pick(rng) == 0 ? col_linear_value(rng, 100, infinite) : 50.0;
  }
  return in;
}

void expect_columns_equal_rows(const core::Machine& m, bool infinite) {
  SCOPED_TRACE(m.name + (infinite ? " with infinities" : ""));
  const auto kin = make_kinematics(m);
  std::mt19937_64 rng(919);
  const ColInput in = col_random_rows(m, 6000, rng, infinite);
  const Eigen::Index n = in.q.rows();
  // The reference, pose by pose.
  Eigen::MatrixXd ref_tip(n, 3), ref_axis(n, 3), ref_vel(n, 3);
  for (Eigen::Index k = 0; k < n; ++k) {
    const Eigen::VectorXd q = in.q.row(k).transpose(), qd = in.qd.row(k).transpose();
    const ToolPose p = kin->forward(q, in.tlo[k]);
    ref_tip.row(k) = p.tip_mm.transpose();
    ref_axis.row(k) = p.axis.transpose();
    ref_vel.row(k) = kin->tip_velocity(q, qd, in.tlo[k]).transpose();
  }
  for (const Eigen::Index block : {Eigen::Index{1}, Eigen::Index{7}, n}) {
    SCOPED_TRACE("blocks of " + std::to_string(block));
    Eigen::MatrixXd tip(n, 3), axis(n, 3), vel(n, 3), tip_only(n, 3), none;
    for (Eigen::Index k0 = 0; k0 < n; k0 += block) {
      const Eigen::Index r = std::min(block, n - k0);
      kin->forward_rows(in.q.middleRows(k0, r), in.tlo.segment(k0, r), tip.middleRows(k0, r), axis.middleRows(k0, r));
      kin->forward_rows(in.q.middleRows(k0, r), in.tlo.segment(k0, r), tip_only.middleRows(k0, r), none);
      kin->tip_velocity_rows(in.q.middleRows(k0, r), in.qd.middleRows(k0, r), in.tlo.segment(k0, r),
                             vel.middleRows(k0, r));
    }
    for (Eigen::Index k = 0; k < n; ++k) {
      ASSERT_TRUE(col_same_bits(ref_tip.row(k).transpose(), tip, k)) << "row " << k;
      ASSERT_TRUE(col_same_bits(ref_tip.row(k).transpose(), tip_only, k)) << "row " << k;
      ASSERT_TRUE(col_same_bits(ref_axis.row(k).transpose(), axis, k)) << "row " << k;
      ASSERT_TRUE(col_same_bits(ref_vel.row(k).transpose(), vel, k)) << "row " << k;
    }
  }
}

TEST(KinematicsColumns, MikronTableTableEqualsPerRow) {
  expect_columns_equal_rows(core::load_machine(kColMachines / "mikron_ucp710.toml"), false);
}
TEST(KinematicsColumns, MikronWithInfinitiesEqualsPerRow) {
  expect_columns_equal_rows(core::load_machine(kColMachines / "mikron_ucp710.toml"), true);
}
TEST(KinematicsColumns, XyzacTrtEqualsPerRow) {
  expect_columns_equal_rows(core::load_machine(kColMachines / "xyzac_trt.toml"), false);
}
TEST(KinematicsColumns, HeadHeadEqualsPerRow) { expect_columns_equal_rows(col_head_head_machine(), false); }
TEST(KinematicsColumns, CartesianXyzEqualsPerRow) {
  core::Machine m = core::load_machine(kColMachines / "mikron_ucp710.toml");
  m.kinematics = "xyz";
  m.chain.reset();
  expect_columns_equal_rows(m, false);
  expect_columns_equal_rows(m, true);
}
TEST(KinematicsColumns, OffsetChainEqualsPerRow) {
  expect_columns_equal_rows(col_offset_machine(), false);
  expect_columns_equal_rows(col_offset_machine(), true);
}

}  // namespace
}  // namespace vmsim::motion
