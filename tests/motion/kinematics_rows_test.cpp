// Kinematics::forward_rows and tip_velocity_rows (issue 21: a run's millions of poses at once) against the per-row
// forward() and tip_velocity() they replace in the run's hot loops, bit for bit, on random rows whose rotary angles
// hold for random runs (the repeats reuse a cached rotation) and change otherwise, with exact zeros and negative zeros
// among them. Machines: the Mikron's table-table chain, LinuxCNC's xyzac-trt, the Mikron made head-head (rotary joints
// on the tool side, off-axis pivots, a linear joint on the workpiece side), and the Cartesian "xyz" machine.
#include "core/error.hpp"
#include "core/machine.hpp"
#include "motion/kinematics.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

namespace vmsim::motion {
namespace {

namespace fs = std::filesystem;

const fs::path kRowsMachines = fs::path(VMSIM_SOURCE_DIR) / "parts" / "machines";

bool rows_same_bits(const Eigen::Vector3d& a, const Eigen::MatrixXd& m, Eigen::Index row) {
  const Eigen::Vector3d b = m.row(row).transpose();
  return std::memcmp(a.data(), b.data(), 3 * sizeof(double)) == 0;
}

// The Mikron with its rotary joints moved to the tool side (pivots off every axis) and X on the workpiece side.
core::Machine rows_head_head_machine() {
  core::Machine m = core::load_machine(kRowsMachines / "mikron_ucp710.toml");
  core::KinematicChain& ch = *m.chain;
  std::vector<core::ChainJoint> rotary = ch.workpiece;
  rotary[0].point_mm = Eigen::Vector3d(3, -4, 120);
  rotary[1].point_mm = Eigen::Vector3d(-2, 5, 80);
  rotary[1].direction = Eigen::Vector3d(0.1, 0.2, -1).normalized();
  ch.workpiece = {ch.tool[0]};
  ch.workpiece[0].direction = -ch.workpiece[0].direction;
  ch.tool = {ch.tool[1], ch.tool[2], rotary[0], rotary[1]};
  ch.gauge_point_mm = Eigen::Vector3d(0.5, -0.25, 40);
  ch.workpiece_origin_mm = Eigen::Vector3d(7, -3, 2);
  return m;
}

// Random axis rows (and velocities, tool length offsets): linear axes anywhere in +-300 mm, rotary ones held for
// runs of 1 to 40 rows at 0, -0, or a random angle.
struct RowsInput {
  Eigen::MatrixXd q, qd;
  Eigen::VectorXd tlo;
};

RowsInput random_rows(const core::Machine& m, Eigen::Index n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> run(1, 40), pick(0, 3);
  const auto axes = static_cast<Eigen::Index>(m.axes.size());
  RowsInput in{Eigen::MatrixXd(n, axes), Eigen::MatrixXd(n, axes), Eigen::VectorXd(n)};
  for (Eigen::Index a = 0; a < axes; ++a) {
    const bool rotary = m.axes[static_cast<std::size_t>(a)].kind == core::AxisKind::Rotary;
    double held = 0;
    int left = 0;
    for (Eigen::Index k = 0; k < n; ++k) {
      if (!rotary) {
        in.q(k, a) = 300 * u(rng);
      } else {
        if (left-- <= 0) {
          left = run(rng);
          const int p = pick(rng);
          held = p == 0 ? 0.0 : p == 1 ? -0.0 : 3 * u(rng);
        }
        in.q(k, a) = held;
      }
      in.qd(k, a) = rotary ? 2 * u(rng) : 500 * u(rng);
    }
  }
  double tlo = 50;
  for (Eigen::Index k = 0; k < n; ++k) {
    if (pick(rng) == 0) tlo = 100 * (1 + u(rng));
    in.tlo[k] = tlo;
  }
  return in;
}

void expect_rows_equal_single(const core::Machine& m) {
  SCOPED_TRACE(m.name + " (" + m.kinematics + ")");
  const auto kin = make_kinematics(m);
  std::mt19937_64 rng(2121);
  const RowsInput in = random_rows(m, 2000, rng);
  const Eigen::Index n = in.q.rows();
  Eigen::MatrixXd tip(n, 3), axis(n, 3), vel(n, 3), tip_only(n, 3), none;
  kin->forward_rows(in.q, in.tlo, tip, axis);
  kin->forward_rows(in.q, in.tlo, tip_only, none);
  kin->tip_velocity_rows(in.q, in.qd, in.tlo, vel);
  int turned = 0;
  for (Eigen::Index k = 0; k < n; ++k) {
    const Eigen::VectorXd q = in.q.row(k).transpose(), qd = in.qd.row(k).transpose();
    const ToolPose p = kin->forward(q, in.tlo[k]);
    ASSERT_TRUE(rows_same_bits(p.tip_mm, tip, k)) << "row " << k;
    ASSERT_TRUE(rows_same_bits(p.axis, axis, k)) << "row " << k;
    ASSERT_TRUE(rows_same_bits(p.tip_mm, tip_only, k)) << "row " << k;
    ASSERT_TRUE(rows_same_bits(kin->tip_velocity(q, qd, in.tlo[k]), vel, k)) << "row " << k;
    if ((p.axis - Eigen::Vector3d::UnitZ()).norm() > 1e-3) ++turned;
  }
  // The rows exercise turned tools (not only the held zero angles) on the five-axis machines.
  if (m.kinematics == "chain") {
    EXPECT_GT(turned, n / 4);
  }

  // Rows of a block of a larger matrix (the run passes blocks of its whole arrays), written into a block.
  const Eigen::Index r0 = 123, rows = 700;
  Eigen::MatrixXd tip_all = Eigen::MatrixXd::Zero(n, 3), vel_all = Eigen::MatrixXd::Zero(n, 3);
  kin->forward_rows(in.q.middleRows(r0, rows), in.tlo.segment(r0, rows), tip_all.middleRows(r0, rows), none);
  kin->tip_velocity_rows(in.q.middleRows(r0, rows), in.qd.middleRows(r0, rows), in.tlo.segment(r0, rows),
                         vel_all.middleRows(r0, rows));
  for (Eigen::Index k = r0; k < r0 + rows; ++k) {
    ASSERT_TRUE(rows_same_bits(Eigen::Vector3d(tip.row(k).transpose()), tip_all, k)) << "row " << k;
    ASSERT_TRUE(rows_same_bits(Eigen::Vector3d(vel.row(k).transpose()), vel_all, k)) << "row " << k;
  }
}

TEST(KinematicsRows, TableTableMikronEqualsForwardRowByRow) {
  expect_rows_equal_single(core::load_machine(kRowsMachines / "mikron_ucp710.toml"));
}

TEST(KinematicsRows, XyzacTrtEqualsForwardRowByRow) {
  expect_rows_equal_single(core::load_machine(kRowsMachines / "xyzac_trt.toml"));
}

TEST(KinematicsRows, HeadHeadEqualsForwardRowByRow) { expect_rows_equal_single(rows_head_head_machine()); }

TEST(KinematicsRows, CartesianEqualsForwardRowByRow) {
  core::Machine m = core::load_machine(kRowsMachines / "mikron_ucp710.toml");
  m.kinematics = "xyz";
  m.chain.reset();
  expect_rows_equal_single(m);
}

TEST(KinematicsRows, ShapesThatDoNotMatchAreErrors) {
  const core::Machine m = core::load_machine(kRowsMachines / "mikron_ucp710.toml");
  const auto kin = make_kinematics(m);
  const Eigen::MatrixXd q = Eigen::MatrixXd::Zero(10, 5), q4 = Eigen::MatrixXd::Zero(10, 4);
  const Eigen::VectorXd tlo = Eigen::VectorXd::Zero(10), tlo9 = Eigen::VectorXd::Zero(9);
  Eigen::MatrixXd tip(10, 3), tip9(9, 3), axis2(10, 2), none;
  EXPECT_THROW(kin->forward_rows(q4, tlo, tip, none), core::Error);
  EXPECT_THROW(kin->forward_rows(q, tlo9, tip, none), core::Error);
  EXPECT_THROW(kin->forward_rows(q, tlo, tip9, none), core::Error);
  EXPECT_THROW(kin->forward_rows(q, tlo, tip, axis2), core::Error);
  EXPECT_THROW(kin->tip_velocity_rows(q, q4, tlo, tip), core::Error);
  EXPECT_THROW(kin->tip_velocity_rows(q, q, tlo, tip9), core::Error);
  EXPECT_NO_THROW(kin->forward_rows(q, tlo, tip, none));
}

}  // namespace
}  // namespace vmsim::motion
