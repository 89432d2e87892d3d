// Contour-error-constrained feed planning (Chen et al. 2016). References: Chen et al.'s Table 2 coefficients; |G(jw)|
// of the transfer function evaluated here directly (bisection written here for eq. 11); the closed forms of eq. 11-13
// and 15 on a circle; the constraints recomputed sample by sample from the path and the feeds (check_feed_plan, which
// does not read the LP's rows); the one-window LP for the windowed one; and the time-domain simulation of the servo
// for the contour error of the played plan.
#include "core/error.hpp"
#include "motion/interp.hpp"
#include "core/machine.hpp"
#include "motion/nurbs.hpp"
#include "methods/feedplan.hpp"
#include "methods/feedplan_play.hpp"
#include "methods/feedplan_servo.hpp"
#include "drives/linear_model.hpp"
#include "core/units.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>

using namespace vmsim;
using methods::FeedPlanOptions;

namespace {

using vmsim::core::units::kPi;
const std::string kFeedplanDir = std::string(VMSIM_SOURCE_DIR) + "/parts/feedplan/";

motion::NurbsCurve curve(const std::string& name) {
  return motion::read_nurbs_csv(kFeedplanDir + name + "_nurbs_control_points.csv",
                                kFeedplanDir + name + "_nurbs_knots.csv", 3);
}

motion::NurbsCurve unit_circle_nurbs(double r) {
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

methods::TransferFunction pid_x() { return methods::pid_servo_transfer_function(methods::chen2016_pid_x()); }
methods::TransferFunction pid_y() { return methods::pid_servo_transfer_function(methods::chen2016_pid_y()); }

// Chen et al. 2016 section 4's limits, the jerk of parts/feedplan/chen2016_machine.toml.
FeedPlanOptions case_options(const methods::ContourErrorModel* model, bool jerk = true) {
  FeedPlanOptions o;
  o.contour_model = model;
  o.limits.period_s = 0.004;
  o.limits.chord_error_mm = 0.0005;
  o.limits.contour_error_mm = 0.020;
  o.limits.max_feed_mm_per_s = 50;
  o.limits.axis_velocity.setConstant(50);
  o.limits.axis_acceleration.setConstant(200);
  if (jerk) o.limits.axis_jerk.setConstant(5000);
  return o;
}

// Eq. 11 written out: the first w where |G(jw)| leaves [1 - x, 1 + x], by a scan then bisection on |G| itself.
double omega0_direct(const methods::TransferFunction& g, double x) {
  auto e = [&](double w) { return std::abs(1.0 - std::abs(g.at_omega(w))); };
  double lo = 0.0, hi = 1e-3;
  while (e(hi) < x) lo = hi, hi *= 1.001;
  for (int i = 0; i < 200; ++i) {
    const double m = 0.5 * (lo + hi);
    (e(m) < x ? lo : hi) = m;
  }
  return lo;
}

}  // namespace

TEST(FeedPlanServo, PidTransferFunctionIsSeedTable2) {
  const methods::TransferFunction g = pid_x();
  ASSERT_EQ(g.num.size(), 3u);
  ASSERT_EQ(g.den.size(), 4u);
  // Table 2 (rounded there to 4-5 digits): A1 s^2 + A2 s + A3 over A4 s^3 + A5 s^2 + A6 s + A7.
  EXPECT_NEAR(g.num[0], 1.4965, 1e-4);
  EXPECT_NEAR(g.num[1], 49.883, 1e-3);
  EXPECT_NEAR(g.num[2], 249.415, 1e-2);
  EXPECT_NEAR(g.den[0], 0.007, 1e-5);
  EXPECT_NEAR(g.den[1], 1.52, 1e-3);
  EXPECT_NEAR(g.den[2], 49.883, 1e-3);
  EXPECT_NEAR(g.den[3], 249.415, 1e-2);
  EXPECT_NEAR(std::abs(g.at_omega(0.0)), 1.0, 1e-15);
}

TEST(FeedPlanServo, TransferFunctionAxisFollowsASineWithGainG) {
  // A sine setpoint at 20 rad/s; after the transients the amplitude ratio is |G(jw)| times the first-order hold's
  // sinc^2(wT/2) (the reference is the line between setpoints).
  const methods::TransferFunction g = pid_x();
  const double te = 1e-3, w = 20.0, amp = 5.0;
  core::Setpoints sp;
  sp.period_s = te;
  const Eigen::Index n = 8000;
  sp.position.resize(n, 1);
  for (Eigen::Index k = 0; k < n; ++k) sp.position(k, 0) = amp * std::sin(w * k * te);
  const Eigen::MatrixXd y = methods::simulate_transfer_functions(sp, {g}, 0.0);
  double peak = 0;
  for (Eigen::Index k = n / 2; k < n; ++k) peak = std::max(peak, std::abs(y(k, 0)));
  const double sinc = std::sin(w * te / 2) / (w * te / 2);
  EXPECT_NEAR(peak / amp, std::abs(g.at_omega(w)) * sinc * sinc, 2e-5);
  // At rest it holds the setpoint exactly (G(0) = 1); an ideal axis ({1}/{1}) is the setpoint delayed by one Te.
  core::Setpoints rest;
  rest.period_s = te;
  rest.position = Eigen::MatrixXd::Constant(50, 2, 3.25);
  rest.position.col(1).setLinSpaced(50, 0.0, 49.0);
  const Eigen::MatrixXd r =
      methods::simulate_transfer_functions(rest, {g, methods::TransferFunction{{1.0}, {1.0}}}, 0.01);
  EXPECT_NEAR((r.col(0).array() - 3.25).abs().maxCoeff(), 0.0, 1e-12);
  EXPECT_NEAR(r(20, 1), 19.0, 1e-12);
}

TEST(FeedPlanServo, ContourErrorModelSolvesEq11) {
  const methods::TransferFunction g = pid_x();
  const methods::ContourErrorModel m({methods::frequency_response(g)});
  // w_n: the resonance peak of |G| (Chen et al.'s PID servo rises to ~1.10 near 50 rad/s).
  const double wn = m.natural_frequency();
  EXPECT_GT(wn, 30.0);
  EXPECT_LT(wn, 80.0);
  EXPECT_GE(std::abs(g.at_omega(wn)), std::abs(g.at_omega(wn * 1.02)));
  EXPECT_GE(std::abs(g.at_omega(wn)), std::abs(g.at_omega(wn / 1.02)));
  for (double x : {1e-5, 1e-3, 4e-3, 0.02, 0.05}) {
    const double w0 = m.omega0(x);
    EXPECT_NEAR(w0, omega0_direct(g, x), 1e-9 * w0) << x;
    EXPECT_NEAR(m.error_ratio(w0), x, 1e-9 * x) << x;
  }
  EXPECT_DOUBLE_EQ(m.omega0(0.5), wn);  // above the peak's error: w_n bounds w0
  // The Mikron's linearised cascade: |G| < 1, the error is inside the circle; at the feed eq. 13 allows, Chen et al.'s
  // circle error R (1 - |G|) is the tolerance.
  const core::Machine mk = core::load_machine(std::string(VMSIM_SOURCE_DIR) + "/parts/machines/mikron_ucp710.toml");
  const drives::LinearAxisModel lx(*mk.axes[0].drive, 1e-3);
  const methods::ContourErrorModel mm({methods::frequency_response(*mk.axes[0].drive, 1e-3)});
  for (double R : {1.0, 5.0, 20.0}) {
    const double f = mm.max_feed(R, 0.020);
    EXPECT_NEAR(lx.circle_radial_error(R, f), 0.020, 1e-9) << R;
  }
}

TEST(FeedPlan, CircleFeedIsTheClosedFormOfEq11To13And15) {
  const motion::NurbsCurve c5 = unit_circle_nurbs(5.0);
  const methods::TransferFunction g = pid_x();
  const methods::ContourErrorModel m({methods::frequency_response(g), methods::frequency_response(g)});
  // Contour error binds: 1 + kappa eps0 = |G(j w0)|, f = w0 rho (the chord allows 35 mm/s, the centripetal
  // acceleration sqrt(A rho) = 31.6 mm/s).
  {
    const methods::PathSamples ps = methods::sample_nurbs(c5, 0.02);
    const methods::FeedPlan p = methods::plan_feed(ps, case_options(&m));
    const double f = omega0_direct(g, 0.020 / 5.0) * 5.0;
    ASSERT_LT(f, 31.0);
    int checked = 0;
    for (Eigen::Index i = 0; i < ps.size(); ++i) {
      if (ps.s[i] < 8 || ps.s[i] > 24) continue;  // away from the start and stop
      EXPECT_NEAR(p.feed[i], f, 1e-6 * f) << ps.s[i];
      ++checked;
    }
    EXPECT_GT(checked, 700);
  }
  // Chord error binds (no contour constraint, a stiffer machine): f = 2 sqrt(rho^2 - (rho - delta)^2) / T.
  {
    const motion::NurbsCurve c1 = unit_circle_nurbs(1.0);
    const methods::PathSamples ps = methods::sample_nurbs(c1, 0.005);
    FeedPlanOptions o = case_options(&m);
    o.limits.contour_error_mm = 0;
    o.limits.axis_acceleration.setConstant(2000);
    o.limits.axis_jerk.setConstant(1e6);
    const methods::FeedPlan p = methods::plan_feed(ps, o);
    const double f = 2 * std::sqrt(1.0 - (1.0 - 0.0005) * (1.0 - 0.0005)) / 0.004;
    for (Eigen::Index i = 0; i < ps.size(); ++i)
      if (ps.s[i] > 2.5 && ps.s[i] < 3.8) {
        EXPECT_NEAR(p.feed[i], f, 1e-6 * f) << ps.s[i];
      }
  }
}

TEST(FeedPlan, EveryConstraintHoldsAtEverySample) {
  const methods::ContourErrorModel m({methods::frequency_response(pid_x()), methods::frequency_response(pid_y())});
  std::vector<methods::PathSamples> paths = {methods::sample_nurbs(curve("butterfly"), 0.05),
                                             methods::sample_nurbs(curve("fan"), 0.05)};
  // A G-code-like path: lines, a tangent arc, a sharp corner blended by the interpolator's smoothing.
  {
    core::ToolPath tp;
    tp.source_path = "program";
    auto v = [](double x, double y) {
      core::Vec6 p = core::Vec6::Zero();
      p[0] = x, p[1] = y;
      return p;
    };
    core::Move a;
    a.start = v(0, 0), a.end = v(20, 0), a.feed_mm_per_min = 3000;
    core::Move b = a;
    b.kind = core::MotionKind::Arc, b.start = v(20, 0), b.end = v(20, 10), b.centre_mm = {20, 5}, b.rotation = 1;
    core::Move c = a;
    c.start = v(20, 10), c.end = v(0, 10);
    core::Move d = a;
    d.start = v(0, 10), d.end = v(0, 30);
    tp.moves = {a, b, c, d};
    const core::Machine mach = core::load_machine(kFeedplanDir + "chen2016_machine.toml");
    motion::InterpOptions io;
    io.period_s = 0.004;
    paths.push_back(methods::sample_path(motion::smooth_path_for(tp, mach, io), 0.05));
  }
  for (std::size_t k = 0; k < paths.size(); ++k) {
    for (int variant = 0; variant < 3; ++variant) {
      FeedPlanOptions o = case_options(&m, variant != 1);
      if (variant == 2) o.limits.contour_error_mm = 0;
      o.window_samples = 1500;  // several windows on the curves
      const methods::FeedPlan p = methods::plan_feed(paths[k], o);
      const methods::FeedPlanCheck c = methods::check_feed_plan(paths[k], p.feed, o.limits, &m);
      EXPECT_LE(c.worst(), 1 + 1e-6) << "path " << k << " variant " << variant << ": feed " << c.feed << " chord "
                                     << c.chord << " contour " << c.contour << " velocity " << c.axis_velocity
                                     << " acceleration " << c.axis_acceleration << " jerk " << c.axis_jerk;
      EXPECT_GT(p.feed.maxCoeff(), 0.9 * o.limits.max_feed_mm_per_s);  // and it is not trivially slow
      if (variant == 1) {
        EXPECT_EQ(p.stats.jerk_iterations_max, 0);
      }
    }
  }
  // The check is not toothless: eq. 24's bound alone (no acceleration rows) breaks the acceleration limit, 5 % over
  // the plan the contour limit, and 2 % over eq. 15's chord bound (at the samples where it is finite) the chord limit.
  const FeedPlanOptions o = case_options(&m);
  const methods::FeedPlan p = methods::plan_feed(paths[0], o);
  Eigen::ArrayXd fstar = p.f_star;
  fstar[0] = fstar[fstar.size() - 1] = 0;
  EXPECT_GT(methods::check_feed_plan(paths[0], fstar, o.limits, &m).axis_acceleration, 1.5);
  EXPECT_GT(methods::check_feed_plan(paths[0], p.feed * 1.05, o.limits, &m).contour, 1.0);
  const Eigen::ArrayXd over_chord = (p.bound_chord.isFinite()).select(p.bound_chord * 1.02, 0.0);
  EXPECT_GT(methods::check_feed_plan(paths[0], over_chord, o.limits, &m).chord, 1.0);
}

TEST(FeedPlan, WindowsAgreeWithOneLinearProgram) {
  const methods::ContourErrorModel m({methods::frequency_response(pid_x()), methods::frequency_response(pid_y())});
  const methods::PathSamples ps = methods::sample_nurbs(curve("butterfly"), 0.05);
  for (bool jerk : {false, true}) {
    FeedPlanOptions o = case_options(&m, jerk);
    o.window_samples = static_cast<int>(ps.size()) + 10;
    const methods::FeedPlan one = methods::plan_feed(ps, o);
    EXPECT_EQ(one.stats.windows, 1);
    o.window_samples = 1000;
    const methods::FeedPlan win = methods::plan_feed(ps, o);
    EXPECT_GE(win.stats.windows, 8);
    const double diff = (win.feed - one.feed).abs().maxCoeff();
    // Acceleration alone: the LP's optimum is the pointwise largest feasible q, which the windows find exactly.
    // With the linearised jerk, each window's fixed point differs a little near its seams.
    EXPECT_LT(diff, jerk ? 0.05 * o.limits.max_feed_mm_per_s : 1e-6 * o.limits.max_feed_mm_per_s) << jerk;
    EXPECT_NEAR(win.time_s, one.time_s, (jerk ? 2e-3 : 1e-7) * one.time_s) << jerk;
  }
}

TEST(FeedPlan, SimulatedContourErrorExceedsWithoutTheConstraintAndHoldsWithIt) {
  // Chen et al. 2016 section 4's case on the butterfly: T = 4 ms, chord 0.5 um, contour 20 um, 50 mm/s, 200 mm/s^2, its
  // PID servo (Table 1, X and Y), played by the interpolator and simulated.
  const motion::NurbsCurve c = curve("butterfly");
  const core::Machine mach = core::load_machine(kFeedplanDir + "chen2016_machine.toml");
  motion::NurbsPathOptions no;
  no.feed_mm_per_min = 3000;
  const motion::NurbsPath np = motion::nurbs_to_path(c, no);
  methods::PlanPlayer pl;
  pl.program = &np.program;
  pl.machine = &mach;
  pl.interp.period_s = 0.004;
  pl.interp.geometry = std::make_shared<const motion::SmoothPath>(np.path);
  pl.to_path_s = [&](double s) { return np.path_s(s); };
  pl.to_sample_s = [&](double s) { return np.curve_s(s); };
  pl.servo = {pid_x(), pid_y(), methods::TransferFunction{{1.0}, {1.0}}};
  const methods::ContourErrorModel m({methods::frequency_response(pid_x()), methods::frequency_response(pid_y())});
  const methods::PathSamples ps = methods::sample_nurbs(c, 0.05);
  // Planned as vmsim plan-feed plans a profile the interpolator follows (PlanPlayer::follow): within the interpolator's
  // own shares of the acceleration and jerk limits.
  FeedPlanOptions o = case_options(&m);
  o.limits.axis_acceleration *= motion::kPlanAccelShare;
  o.limits.axis_jerk *= motion::kPlanJerkShare;
  FeedPlanOptions free = o;
  free.limits.contour_error_mm = 0;
  const methods::FeedPlan fp = methods::plan_feed(ps, free);
  const methods::PlayedPlan without = methods::play_plan(pl, ps, &fp);
  EXPECT_GT(without.max_abs_mm, 0.020 * 1.3);  // Chen et al. 2016: 31.6 um, 58 % over
  const methods::VerifiedPlan with = methods::plan_feed_verified(ps, o, pl);
  EXPECT_TRUE(with.holds);
  EXPECT_LE(with.played.max_abs_mm, 0.020);
  EXPECT_LE(with.rounds, 4);
  // Played as planned (issue 23 section 3): within 5 % of the plan's own time.
  EXPECT_LE(with.played.interp.stats.cycle_time_s, 1.05 * with.plan.time_s);
  // The verified plan still keeps every constraint, and the interpolator kept its limits and the chord error.
  EXPECT_LE(methods::check_feed_plan(ps, with.plan.feed, o.limits, &m).worst(), 1 + 1e-6);
  EXPECT_LE(with.played.chord_error_mm.maxCoeff(), 0.0005);
  const core::AxisPeaks peaks = core::finite_difference_peaks(with.played.interp.setpoints);
  for (int a = 0; a < 2; ++a) {
    EXPECT_LE(peaks.velocity[a], 50 * (1 + 1e-9));
    EXPECT_LE(peaks.acceleration[a], 200 * (1 + 1e-9));
    EXPECT_LE(peaks.jerk[a], 5000 * (1 + 1e-9));
  }
}

TEST(FeedPlan, BadInputIsAnError) {
  const methods::PathSamples ps = methods::sample_nurbs(unit_circle_nurbs(5), 0.1);
  FeedPlanOptions o = case_options(nullptr);
  EXPECT_THROW(methods::plan_feed(ps, o), core::Error);  // a contour tolerance without a servo model
  o.limits.contour_error_mm = 0;
  o.limits.axis_acceleration[1] = 0;
  EXPECT_THROW(methods::plan_feed(ps, o), core::Error);
  const methods::ContourErrorModel m({methods::frequency_response(pid_x())});
  o = case_options(&m);
  o.contour_scale = Eigen::ArrayXd::Constant(ps.size() - 1, 0.5);
  EXPECT_THROW(methods::plan_feed(ps, o), core::Error);
  EXPECT_THROW(methods::sample_nurbs(unit_circle_nurbs(5), 0.0), core::Error);
  EXPECT_THROW(methods::ContourErrorModel({methods::frequency_response(methods::TransferFunction{{2.0}, {1.0, 1.0}})}),
               core::Error);  // G(0) = 2 is not a position servo
}
