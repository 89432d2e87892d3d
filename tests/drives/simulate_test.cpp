// simulate_axes: all axes of a machine from the interpolator's setpoints. Thread-count independence, the gain
// schedule, the response's time base, and the errors a user gets.
#include "drives/simulate.hpp"

#include "core/error.hpp"
#include "motion/interp.hpp"
#include "motion/kinematics.hpp"
#include "program/program.hpp"
#include "tests/drives/drive_test_support.hpp"
#include "tests/test_paths.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <limits>

namespace vmsim::drives {
namespace {

using vmsim::test::kPartsPath;

// A realistic setpoint stream: the plane-cylinder part's 10 m/min pass interpolated for the Mikron (X, Y, Z move;
// A and C have drives and hold their position; Z holds its head against gravity).
core::Setpoints plane_cylinder_setpoints(const core::Machine& m) {
  program::ProgramOptions po;
  po.tool_table = kPartsPath / "plane_cylinder/tools.tbl";
  const core::ToolPath tp = motion::toolpath_in_axis_space(
      program::read_program(kPartsPath / "plane_cylinder/plane_cylinder_fast.ngc", po), m);
  return motion::interpolate(tp, m, motion::InterpOptions{}).setpoints;
}

// Every column, bit for bit (exact equality; NaN would fail it too).
void expect_same_rows(const AxisResponse& a, const AxisResponse& b) {
  ASSERT_EQ(a.samples(), b.samples());
  EXPECT_TRUE((a.position.array() == b.position.array()).all());
  EXPECT_TRUE((a.velocity.array() == b.velocity.array()).all());
  EXPECT_TRUE((a.acceleration.array() == b.acceleration.array()).all());
  EXPECT_TRUE((a.jerk.array() == b.jerk.array()).all());
  EXPECT_TRUE((a.current_A.array() == b.current_A.array()).all());
  EXPECT_TRUE((a.current_setpoint_A.array() == b.current_setpoint_A.array()).all());
  EXPECT_TRUE((a.current_mean_A.array() == b.current_mean_A.array()).all());
  EXPECT_TRUE((a.current_peak_A.array() == b.current_peak_A.array()).all());
}

// Every column and the per-period trace, bit for bit.
void expect_identical(const AxisResponse& a, const AxisResponse& b) {
  expect_same_rows(a, b);
  ASSERT_EQ(a.trace.size(), b.trace.size());
  for (std::size_t i = 0; i < a.trace.size(); ++i) {
    EXPECT_TRUE((a.trace[i].position == b.trace[i].position).all());
    EXPECT_TRUE((a.trace[i].current_A == b.trace[i].current_A).all());
    EXPECT_TRUE((a.trace[i].voltage_V == b.trace[i].voltage_V).all());
  }
}

// Reference: each axis is simulated independently (no coupling in the model), in its own columns; the result must
// not depend on how many threads share the axes (DESIGN.md conventions).
TEST(SimulateAxes, IdenticalWithOneAndTwoThreads) {
  const core::Machine m = test::mikron();
  const core::Setpoints sp = plane_cylinder_setpoints(m);
  ASSERT_GT(sp.samples(), 1000);
  SimulateOptions o;
  o.full_rate_trace = true;
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const AxisResponse one = simulate_axes(sp, m, o);
  omp_set_num_threads(2);
  const AxisResponse two = simulate_axes(sp, m, o);
  omp_set_num_threads(saved);
  expect_identical(one, two);
  EXPECT_EQ(one.trace.size(), m.axes.size());
}

// Reference: a gain schedule (Duong et al.'s OGA) whose every entry equals the drive's own Kv and KF is no schedule at
// all: bit-identical results; NaN entries keep the drive's own gains, so an all-NaN schedule is also identical. A
// changed Kv on X changes X's response and no other axis'.
TEST(SimulateAxes, GainScheduleEqualToTheDrivesOwnChangesNothing) {
  const core::Machine m = test::mikron();
  const core::Setpoints sp = plane_cylinder_setpoints(m);
  const AxisResponse plain = simulate_axes(sp, m);
  const Eigen::Index n = sp.samples(), na = static_cast<Eigen::Index>(m.axes.size());
  GainSchedule own;
  own.kv_per_s.resize(n, na);
  own.kf.resize(n, na);
  for (Eigen::Index a = 0; a < na; ++a) {
    own.kv_per_s.col(a).setConstant(m.axes[static_cast<std::size_t>(a)].drive->kv_per_s);
    own.kf.col(a).setConstant(m.axes[static_cast<std::size_t>(a)].drive->kf);
  }
  SimulateOptions o;
  o.gains = &own;
  expect_identical(plain, simulate_axes(sp, m, o));

  GainSchedule nan;
  nan.kv_per_s.setConstant(n, na, std::numeric_limits<double>::quiet_NaN());
  o.gains = &nan;
  expect_identical(plain, simulate_axes(sp, m, o));

  GainSchedule changed = own;
  changed.kv_per_s.col(0).setConstant(0.5 * m.axes[0].drive->kv_per_s);
  o.gains = &changed;
  const AxisResponse slow = simulate_axes(sp, m, o);
  const double dx = (slow.position.col(0) - plain.position.col(0)).cwiseAbs().maxCoeff();
  EXPECT_GT(dx, 1e-3) << "halving X's Kv must change X's response";
  for (Eigen::Index a = 1; a < na; ++a)
    EXPECT_TRUE((slow.position.col(a).array() == plain.position.col(a).array()).all());
  // Half the gain, about twice the following error at the pass's steady feed.
  const double e_plain = (sp.position.col(0) - plain.position.col(0).head(n)).cwiseAbs().maxCoeff();
  const double e_slow = (sp.position.col(0) - slow.position.col(0).head(n)).cwiseAbs().maxCoeff();
  EXPECT_GT(e_slow / e_plain, 1.5);
}

// The blocks of a BlockSimulation put together, as one response.
AxisResponse blocked(const core::Setpoints& sp, const core::Machine& m, const SimulateOptions& o, Eigen::Index block) {
  BlockSimulation sim(sp, m, o);
  AxisResponse whole;
  const Eigen::Index na = static_cast<Eigen::Index>(m.axes.size());
  std::vector<Eigen::MatrixXd*> cols = {&whole.position,       &whole.velocity,      &whole.acceleration,
                                        &whole.jerk,           &whole.current_A,     &whole.current_setpoint_A,
                                        &whole.current_mean_A, &whole.current_peak_A};
  for (Eigen::MatrixXd* c : cols) c->resize(sim.rows(), na);
  while (!sim.done()) {
    const Eigen::Index k0 = sim.next_row();
    const AxisResponse b = sim.next(block);
    EXPECT_LE(b.samples(), block);
    const std::vector<const Eigen::MatrixXd*> bc = {&b.position,       &b.velocity,      &b.acceleration,
                                                    &b.jerk,           &b.current_A,     &b.current_setpoint_A,
                                                    &b.current_mean_A, &b.current_peak_A};
    for (std::size_t i = 0; i < cols.size(); ++i) cols[i]->middleRows(k0, b.samples()) = *bc[i];
  }
  return whole;
}


// Reference: simulate_axes over the whole run. The drives' simulation in blocks (issue 21: the response of a long
// program streamed) carries every drive's state, the NC's previous setpoint and velocity (the feedforward's
// differences), the previous acceleration (the jerk's) and the gain schedule's row across the blocks: at blocks of
// 1, 7 and 65 536 rows the rows are the whole run's bit for bit, with a gain schedule that changes on every row too.
TEST(SimulateAxes, BlocksGiveTheWholeRunBitForBit) {
  const core::Machine m = test::mikron();
  const core::Setpoints sp = plane_cylinder_setpoints(m);
  ASSERT_GT(sp.samples(), 1000);
  const AxisResponse whole = simulate_axes(sp, m);
  for (const Eigen::Index block : {Eigen::Index{1}, Eigen::Index{7}, Eigen::Index{65536}}) {
    SCOPED_TRACE(block);
    expect_same_rows(whole, blocked(sp, m, {}, block));
  }
  // A schedule whose X gain changes every row: a block must read the schedule at its own rows.
  GainSchedule g;
  const Eigen::Index n = sp.samples(), na = static_cast<Eigen::Index>(m.axes.size());
  g.kv_per_s.setConstant(n, na, std::numeric_limits<double>::quiet_NaN());
  for (Eigen::Index k = 0; k < n; ++k) g.kv_per_s(k, 0) = m.axes[0].drive->kv_per_s * (0.6 + 0.4 * ((k / 37) % 2));
  SimulateOptions o;
  o.gains = &g;
  const AxisResponse sched = simulate_axes(sp, m, o);
  EXPECT_FALSE((sched.position.col(0).array() == whole.position.col(0).array()).all());
  expect_same_rows(sched, blocked(sp, m, o, 7));
  // The last block ends with the settling rows; a block past the end is empty.
  BlockSimulation sim(sp, m);
  EXPECT_EQ(sim.rows(), whole.samples());
  while (!sim.done()) sim.next(100000);
  EXPECT_EQ(sim.next(10).samples(), 0);
  EXPECT_THROW(sim.next(0), core::Error);
  o.gains = nullptr;
  o.full_rate_trace = true;
  EXPECT_THROW(BlockSimulation(sp, m, o), core::Error);
}

// Reference: the response's time base (simulate.hpp): row k is the axis at t = k Te; row 0 the resting state at
// the first setpoint; settle_s more rows with the last setpoint held; v_d, a_d by backward differences; jerk the
// backward difference of the accelerations; the trace's sample n at t = n Tc, its every Te-th sample equal to the
// rows.
TEST(SimulateAxes, TimeBaseRowsAndTrace) {
  const core::Machine m = test::only_axes(test::mikron(), {"X", "Z"});
  const double te = 1e-3;
  const core::Setpoints sp = test::sampled(m, te, 500, [](double t, double* p) {
    p[0] = 5.0 + 10.0 * t * t;  // accelerating from rest
    p[1] = -20.0;               // Z holds against gravity
  });
  SimulateOptions o;
  o.settle_s = 0.3;
  o.full_rate_trace = true;
  const AxisResponse r = simulate_axes(sp, m, o);
  ASSERT_EQ(r.samples(), 500 + 300);
  EXPECT_EQ(r.axis_names, (std::vector<std::string>{"X", "Z"}));
  EXPECT_EQ(r.position(0, 0), 5.0);
  EXPECT_EQ(r.velocity(0, 0), 0.0);
  EXPECT_NEAR(r.position(r.samples() - 1, 0), sp.position(499, 0), 1e-4) << "settled on the last setpoint";
  EXPECT_NEAR(r.position(r.samples() - 1, 1), -20.0, 1e-6) << "Z holds its head";
  EXPECT_NEAR(r.current_A(0, 1), m.axes[1].drive->gravity_Nm / m.axes[1].drive->torque_constant_Nm_per_A, 1e-12);
  for (Eigen::Index k = 1; k < r.samples(); ++k) {
    // The model differences motor speeds before scaling to axis units: equal up to rounding.
    const double a = (r.velocity(k, 0) - r.velocity(k - 1, 0)) / te;
    EXPECT_NEAR(r.acceleration(k, 0), a, 1e-9 * (1.0 + std::abs(a))) << k;
    EXPECT_DOUBLE_EQ(r.jerk(k, 0), (r.acceleration(k, 0) - r.acceleration(k - 1, 0)) / te) << k;
  }
  const FullRateTrace& t = r.trace[0];
  EXPECT_DOUBLE_EQ(t.period_s, 62.5e-6);
  const Eigen::Index per = 16;
  ASSERT_EQ(t.position.size(), (r.samples() - 1) * per + 1);
  for (Eigen::Index k = 0; k < r.samples(); ++k) {
    ASSERT_EQ(t.position[k * per], r.position(k, 0)) << k;
    ASSERT_EQ(t.current_A[k * per], r.current_A(k, 0)) << k;
  }
}

// Reference: an axis the setpoints move needs its [axes.drive]; the error names the machine file and the axis. An
// axis without a drive that never moves is held at its position.
TEST(SimulateAxes, AxisWithoutDrive) {
  core::Machine m = test::only_axes(test::mikron(), {"X", "Y"});
  m.axes[1].drive.reset();
  const core::Setpoints still_y = test::sampled(m, 1e-3, 200, [](double t, double* p) {
    p[0] = 100.0 * t;
    p[1] = 7.0;
  });
  const AxisResponse r = simulate_axes(still_y, m);
  EXPECT_TRUE((r.position.col(1).array() == 7.0).all());
  EXPECT_GT(r.position(199, 0), 1.0);

  const core::Setpoints moving_y = test::sampled(m, 1e-3, 200, [](double t, double* p) {
    p[0] = 0.0;
    p[1] = 50.0 * t;
  });
  try {
    simulate_axes(moving_y, m);
    FAIL() << "expected core::Error";
  } catch (const core::Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("mikron_ucp710.toml"), std::string::npos) << msg;
    EXPECT_NE(msg.find("axis Y"), std::string::npos) << msg;
    EXPECT_NE(msg.find("[axes.drive]"), std::string::npos) << msg;
  }
}

// Reference: malformed inputs are refused with a message, not clamped (DESIGN.md conventions).
TEST(SimulateAxes, RefusesMalformedInput) {
  const core::Machine m = test::only_axes(test::mikron(), {"X", "Y"});
  const core::Setpoints sp = test::sampled(m, 1e-3, 50, [](double t, double* p) { p[0] = p[1] = t; });
  GainSchedule g;
  g.kv_per_s.setConstant(49, 2, 100.0);  // one row short
  SimulateOptions o;
  o.gains = &g;
  EXPECT_THROW(simulate_axes(sp, m, o), core::Error);
  g.kv_per_s.setConstant(50, 2, -1.0);
  EXPECT_THROW(simulate_axes(sp, m, o), core::Error);
  core::Setpoints bad = sp;
  bad.period_s = 0.7e-3;  // not a multiple of the 125 us velocity loop
  try {
    simulate_axes(bad, m);
    FAIL() << "expected core::Error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("axis X"), std::string::npos) << e.what();
  }
  bad = sp;
  bad.position(3, 1) = std::nan("");
  EXPECT_THROW(simulate_axes(bad, m), core::Error);
}

}  // namespace
}  // namespace vmsim::drives
