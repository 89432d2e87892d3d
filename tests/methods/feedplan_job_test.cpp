// A job's [feedplan] turned into the plan's inputs (methods/feedplan_job): the limits mapped from the machine file,
// the servo chosen, and eq. 7's estimate. References: Chen et al. 2016 Table 3 (50 mm/s, 200 mm/s^2) and the jerk
// of parts/feedplan/chen2016_machine.toml (5 m/s^3), converted by hand; Chen et al.'s Table 1 PID through
// pid_servo_transfer_function (whose coefficients tests/methods/feedplan_test.cpp holds against Table 2); eq. 7
// evaluated here straight from G(jw) on a circle.
#include "core/error.hpp"
#include "core/job.hpp"
#include "core/machine.hpp"
#include "methods/feedplan_job.hpp"
#include "tests/test_paths.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

using namespace vmsim;

namespace {

using vmsim::test::kPartsDir;
constexpr double kInf = std::numeric_limits<double>::infinity();

core::FeedPlanSpec::Axis pid_axis(const std::string& name, const methods::PidServoParams& p) {
  core::FeedPlanSpec::Axis a;
  a.name = name;
  a.kp = p.kp, a.ki = p.ki, a.kd = p.kd, a.ka = p.ka, a.kt = p.kt, a.inertia = p.inertia, a.damping = p.damping,
  a.rg = p.rg;
  return a;
}

core::FeedPlanSpec chen_spec() {
  core::FeedPlanSpec s;
  s.servo = core::FeedPlanSpec::Servo::Pid;
  s.axes = {pid_axis("X", methods::chen2016_pid_x()), pid_axis("Y", methods::chen2016_pid_y())};
  return s;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const core::Error& e) {
    return e.what();
  }
  return "";
}

// A circle of radius r as a rational quadratic NURBS.
motion::NurbsCurve circle(double r) {
  motion::NurbsCurve n;
  n.degree = 2;
  const double w = std::sqrt(0.5);
  const double xs[9] = {1, 1, 0, -1, -1, -1, 0, 1, 1}, ys[9] = {0, 1, 1, 1, 0, -1, -1, -1, 0};
  for (int i = 0; i < 9; ++i) {
    n.points.emplace_back(r * xs[i], r * ys[i], 0);
    n.weights.push_back(i % 2 ? w : 1.0);
  }
  n.knots = {0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1};
  return n;
}

}  // namespace

TEST(FeedPlanJob, LimitsAreTheMachineFilesInMillimetresPerSecond) {
  const core::Machine m = core::load_machine(kPartsDir + "feedplan/chen2016_machine.toml");
  core::FeedPlanSpec spec = chen_spec();
  spec.chord_error_mm = 0.0005;
  spec.contour_error_mm = 0.02;
  const Eigen::Vector3d xy(1, 1, 0);
  const methods::FeedPlanLimits lim = methods::feed_plan_limits(spec, m, 0.004, 50.0, xy);
  EXPECT_EQ(lim.period_s, 0.004);
  EXPECT_EQ(lim.chord_error_mm, 0.0005);
  EXPECT_EQ(lim.contour_error_mm, 0.02);
  EXPECT_EQ(lim.max_feed_mm_per_s, 50.0);
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(lim.axis_velocity[a], 50.0, 1e-9) << a;       // 3 m/min
    EXPECT_NEAR(lim.axis_acceleration[a], 200.0, 1e-9) << a;  // 0.2 m/s^2
    EXPECT_NEAR(lim.axis_jerk[a], 5000.0, 1e-9) << a;         // 5 m/s^3
  }
  spec.jerk = false;
  EXPECT_EQ(methods::feed_plan_limits(spec, m, 0.004, 50.0, xy).axis_jerk[0], kInf);
  // The Mikron UCP 710 (Duong et al. Table I): X 30 m/min, 2.5 m/s^2, 10 m/s^3; Z 30 m/min, 2.1 m/s^2, 100 m/s^3.
  const core::Machine mikron = core::load_machine(kPartsDir + "machines/mikron_ucp710.toml");
  const methods::FeedPlanLimits mk = methods::feed_plan_limits(chen_spec(), mikron, 0.001, 80.0, xy);
  EXPECT_NEAR(mk.axis_velocity[0], 500.0, 1e-9);
  EXPECT_NEAR(mk.axis_acceleration[0], 2500.0, 1e-9);
  EXPECT_NEAR(mk.axis_jerk[0], 10000.0, 1e-9);
  EXPECT_NEAR(mk.axis_acceleration[2], 2100.0, 1e-9);
  EXPECT_NEAR(mk.axis_jerk[2], 100000.0, 1e-9);
}

TEST(FeedPlanJob, AnAxisTheMachineLacksHasNoLimitUnlessThePathMovesIt) {
  core::Machine m = core::load_machine(kPartsDir + "feedplan/chen2016_machine.toml");
  m.axes.pop_back();  // no Z
  const methods::FeedPlanLimits lim = methods::feed_plan_limits(chen_spec(), m, 0.004, 50.0, Eigen::Vector3d(1, 1, 0));
  EXPECT_EQ(lim.axis_velocity[2], kInf);
  EXPECT_EQ(lim.axis_acceleration[2], kInf);
  const std::string e =
      error_of([&] { methods::feed_plan_limits(chen_spec(), m, 0.004, 50.0, Eigen::Vector3d(1, 1, 1)); });
  EXPECT_NE(e.find("moves axis Z"), std::string::npos) << e;
}

TEST(FeedPlanJob, ServoChoice) {
  const core::Machine chen = core::load_machine(kPartsDir + "feedplan/chen2016_machine.toml");
  const Eigen::Vector3d xy(1, 1, 0);
  // pid: Chen et al.'s eq. 2 per named axis, an ideal axis for Z; the model's responses are the moving axes'.
  const methods::FeedPlanServo s = methods::feed_plan_servo(chen_spec(), chen, 0.004, xy, "job.toml");
  ASSERT_EQ(s.simulate.size(), 3u);
  const methods::TransferFunction x = methods::pid_servo_transfer_function(methods::chen2016_pid_x());
  const methods::TransferFunction y = methods::pid_servo_transfer_function(methods::chen2016_pid_y());
  EXPECT_EQ(s.simulate[0].num, x.num);
  EXPECT_EQ(s.simulate[0].den, x.den);
  EXPECT_EQ(s.simulate[1].num, y.num);
  EXPECT_EQ(s.simulate[2].num, std::vector<double>{1.0});
  EXPECT_EQ(s.simulate[2].den, std::vector<double>{1.0});
  ASSERT_EQ(s.responses.size(), 2u);
  EXPECT_NEAR(std::abs(s.responses[1].g(30.0) - y.at_omega(30.0)), 0.0, 1e-15);
  // A moving axis without its [[feedplan.axis]]: an error naming the job file and the axis.
  core::FeedPlanSpec only_x = chen_spec();
  only_x.axes.pop_back();
  std::string e = error_of([&] { methods::feed_plan_servo(only_x, chen, 0.004, xy, "job.toml"); });
  EXPECT_NE(e.find("job.toml"), std::string::npos) << e;
  EXPECT_NE(e.find("axis Y moves"), std::string::npos) << e;
  // servo = "machine" on a machine without [axes.drive]: an error naming the machine file.
  core::FeedPlanSpec machine = chen_spec();
  machine.servo = core::FeedPlanSpec::Servo::Machine;
  e = error_of([&] { methods::feed_plan_servo(machine, chen, 0.004, xy, "job.toml"); });
  EXPECT_NE(e.find("chen2016_machine.toml"), std::string::npos) << e;
  EXPECT_NE(e.find("[axes.drive]"), std::string::npos) << e;
  // ... and on the Mikron, whose axes have cascades: their linearised responses, nothing to simulate but the cascades.
  const core::Machine mikron = core::load_machine(kPartsDir + "machines/mikron_ucp710.toml");
  const methods::FeedPlanServo ms = methods::feed_plan_servo(machine, mikron, 0.001, xy, "job.toml");
  EXPECT_EQ(ms.responses.size(), 2u);
  EXPECT_TRUE(ms.simulate.empty());
  EXPECT_TRUE(methods::feed_plan_transfer_functions(machine, mikron, "job.toml").empty());
  // transfer_function: G(s) as given; an improper one is an error naming the axis.
  core::FeedPlanSpec tf;
  tf.servo = core::FeedPlanSpec::Servo::TransferFunction;
  tf.axes.resize(1);
  tf.axes[0].name = "X";
  tf.axes[0].num = {1.0, 2.0, 3.0};
  tf.axes[0].den = {1.0, 3.0};
  e = error_of([&] { methods::feed_plan_servo(tf, chen, 0.004, Eigen::Vector3d(1, 0, 0), "job.toml"); });
  EXPECT_NE(e.find("[[feedplan.axis]] X"), std::string::npos) << e;
}

TEST(FeedPlanJob, ModelPeakIsEq7OnACircle) {
  const double r = 4.0;
  const methods::PathSamples ps = methods::sample_nurbs(circle(r), 0.05);
  EXPECT_EQ(methods::moving_axes(ps), Eigen::Vector3d(1, 1, 0));
  const methods::TransferFunction x = methods::pid_servo_transfer_function(methods::chen2016_pid_x());
  const methods::TransferFunction y = methods::pid_servo_transfer_function(methods::chen2016_pid_y());
  const methods::ContourErrorModel model({methods::frequency_response(x), methods::frequency_response(y)});
  for (double f : {5.0, 20.0, 50.0}) {
    const Eigen::ArrayXd feed = Eigen::ArrayXd::Constant(ps.size(), f);
    const double w = f / r;
    const double direct =
        r * std::max(std::abs(1.0 - std::abs(x.at_omega(w))), std::abs(1.0 - std::abs(y.at_omega(w))));
    EXPECT_NEAR(methods::model_contour_peak(ps, feed, model), direct, 1e-6 * direct) << f;
  }
}
