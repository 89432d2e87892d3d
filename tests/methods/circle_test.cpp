// Circle tests of the cascade (the classic servo test: X and Y follow a sampled circle): the steady radial error
// against the linearised frequency response (drives/linear_model), the velocity feedforward's effect, and the
// quadrant glitches Coulomb friction leaves at the axis reversals. Machine: the Mikron UCP 710's X and Y drives
// from parts/machines/mikron_ucp710.toml, as documented there; any change for a test is stated in the test.
#include "drives/linear_model.hpp"
#include "drives/simulate.hpp"

#include "tests/drives/drive_test_support.hpp"
#include "core/units.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

namespace vmsim::methods {
namespace {

using vmsim::core::units::kPi;
constexpr double kTe = 1e-3;

struct Circle {
  double radius = 10.0, speed = 0.0;  // mm, mm/s
  double omega() const { return speed / radius; }
  double period() const { return 2 * kPi / omega(); }
};

struct CircleRun {
  core::Setpoints setpoints;
  drives::AxisResponse response;
  Eigen::Index first = 0, last = 0;  // the last whole revolution: rows [first, last)
};

// Counter-clockwise from (R, 0): x = R cos(w t), y = R sin(w t), sampled at Te; the last whole revolution of
// `revolutions` is measured (the earlier ones let the start-up transient decay: the slowest closed-loop poles
// are a few 1/Kv = 10 ms).
CircleRun run_circle(const core::Machine& m, const Circle& c, int revolutions, bool trace = false) {
  CircleRun run;
  const auto n = static_cast<Eigen::Index>(std::ceil(revolutions * c.period() / kTe)) + 1;
  run.setpoints = drives::test::sampled(m, kTe, n, [&](double t, double* p) {
    p[0] = c.radius * std::cos(c.omega() * t);
    p[1] = c.radius * std::sin(c.omega() * t);
  });
  drives::SimulateOptions o;
  o.settle_s = 0.0;
  o.full_rate_trace = trace;
  run.response = drives::simulate_axes(run.setpoints, m, o);
  run.last = n;
  run.first = n - static_cast<Eigen::Index>(std::floor(c.period() / kTe));
  return run;
}

double radius_at(const drives::AxisResponse& r, Eigen::Index k) {
  return std::hypot(r.position(k, 0), r.position(k, 1));
}

double angle_deg(const Circle& c, Eigen::Index k) {
  const double a = std::fmod(c.omega() * static_cast<double>(k) * kTe, 2 * kPi);
  return a * 180.0 / kPi;
}

core::Machine xy_without_coulomb() {
  core::Machine m = drives::test::only_axes(drives::test::mikron(), {"X", "Y"});
  for (auto& ax : m.axes) ax.drive->coulomb_Nm = 0.0;  // linearisation: viscous friction only
  return m;
}

// Reference: the linearised closed-loop response G = X/X_d of one axis (drives/linear_model), computed in the
// frequency domain without running the simulation. For a circle of radius R at speed v both axes see sinusoids of
// w = v/R a quarter period apart, so in steady state the actual radius is R |G(jw)|: the radial error is
// R (1 - |G|) (Chen et al.'s circular contour-error model). Checked within 2 % for both evaluations of G: from the loop
// elements (ZOHs, delays, rate changes, aliasing neglected) and lifted sampled-data (exact for the linear cascade).
// Coulomb friction is off (viscous only); the test checks that no limit was hit during the measured revolution
// (the voltage saturates on the Mikron when the staircase velocity command steps by more than about 2 m/s^2 x Te,
// e.g. R = 10 mm at 10 m/min, where the system is no longer linear).
TEST(Circle, SteadyRadialErrorMatchesTheLinearisedFrequencyResponse) {
  const core::Machine m = xy_without_coulomb();
  const core::DriveParams& p = *m.axes[0].drive;
  const drives::LinearAxisModel model(p, kTe);
  const Circle circles[] = {{10.0, 1000.0 / 60}, {10.0, 3000.0 / 60}, {10.0, 5000.0 / 60}, {50.0, 10000.0 / 60}};
  for (const Circle& c : circles) {
    const CircleRun run = run_circle(m, c, 3, true);
    const drives::AxisResponse& r = run.response;
    // Linearity: no saturation in the measured revolution, at every current-loop sample.
    const auto nin = r.trace[0].position.size() / (r.samples() - 1);
    for (int a = 0; a < 2; ++a) {
      const drives::FullRateTrace& t = r.trace[static_cast<std::size_t>(a)];
      const auto from = run.first * nin, count = (run.last - 1 - run.first) * nin;
      ASSERT_LT(t.voltage_V.segment(from, count).abs().maxCoeff(), p.voltage_limit_V);
      ASSERT_LT(t.current_setpoint_A.segment(from, count).abs().maxCoeff(), p.current_limit_A);
    }
    double sum = 0.0, lo = 1e300, hi = -1e300;
    for (Eigen::Index k = run.first; k < run.last; ++k) {
      const double e = c.radius - radius_at(r, k);
      sum += e;
      lo = std::min(lo, e);
      hi = std::max(hi, e);
    }
    const double sim = sum / static_cast<double>(run.last - run.first);
    const double w = c.omega();
    const double lifted = c.radius * (1.0 - std::abs(model.closed_loop(w)));
    const double elements = c.radius * (1.0 - std::abs(model.closed_loop_elements(w)));
    std::printf(
        "circle R %g mm at %g m/min (w %.3f rad/s): simulated radial error %.6e mm (spread %.1e), "
        "R(1-|G|) elements %.6e (%+.5f %%), lifted %.6e (%+.5f %%)\n",
        c.radius, c.speed * 0.06, w, sim, hi - lo, elements, 100 * (sim / elements - 1), lifted,
        100 * (sim / lifted - 1));
    EXPECT_NEAR(sim / elements, 1.0, 0.02) << "R " << c.radius << " v " << c.speed;
    EXPECT_NEAR(sim / lifted, 1.0, 0.02) << "R " << c.radius << " v " << c.speed;
    EXPECT_GT(sim, 0.0) << "a P position loop with KF < 1 cuts inside the circle";
  }
}

// Reference: with KF = 1 the velocity feedforward supplies the whole velocity command, so the P loop's velocity
// lag v/Kv disappears (the feed-drive simulation paper section 3.2: feedforward "cancels dragging differences"); what
// remains is the dead time of the setpoint transfer (the machine file's one Te in both paths, which no feedforward can
// remove: v d Te) and the inner loops' lag. Required: the tracking error |P_d(t_k) - P(t_k)| on a circle at least 10x
// smaller with KF = 1 than with KF = 0. The Mikron drives as they are in the machine file (Coulomb friction
// included), only KF changed.
TEST(Circle, VelocityFeedforwardCutsTheTrackingErrorTenfold) {
  const core::Machine base = drives::test::only_axes(drives::test::mikron(), {"X", "Y"});
  core::Machine m0 = base, m1 = base;
  for (auto& ax : m0.axes) ax.drive->kf = 0.0;
  for (auto& ax : m1.axes) ax.drive->kf = 1.0;
  const int d = base.axes[0].drive->position_delay_samples;
  for (double feed : {1000.0, 3000.0, 5000.0}) {
    const Circle c{10.0, feed / 60};
    const CircleRun r0 = run_circle(m0, c, 2), r1 = run_circle(m1, c, 2);
    // max over the last revolution of the tracking error, against the setpoint of the same instant and against
    // the one the position loop works on (d samples older).
    auto worst = [&](const CircleRun& r, int delay) {
      double e = 0.0;
      for (Eigen::Index k = r.first; k < r.last; ++k)
        e = std::max(e, std::hypot(r.setpoints.position(k - delay, 0) - r.response.position(k, 0),
                                   r.setpoints.position(k - delay, 1) - r.response.position(k, 1)));
      return e;
    };
    const double e0 = worst(r0, 0), e1 = worst(r1, 0);
    std::printf(
        "circle R 10 mm at %g m/min: tracking error KF=0 %.4e mm, KF=1 %.4e mm: %.1fx less "
        "(v d Te = %.4e mm; against the delayed setpoint %.1fx less)\n",
        feed / 1000, e0, e1, e0 / e1, c.speed * d * kTe, worst(r0, d) / worst(r1, d));
    EXPECT_GE(e0 / e1, 10.0) << feed;
    // The remainder is the dead time's v d Te (and a little inner-loop lag and friction).
    EXPECT_NEAR(e1 / (c.speed * d * kTe), 1.0, 0.1) << feed;
    EXPECT_GE(worst(r0, d) / worst(r1, d), 50.0) << feed;
  }
}

// Reference: Coulomb friction makes each axis stick when its velocity reverses: the velocity PI must swing the
// current through the friction band (+-Tc/Kt) before the axis moves again. X reverses where its velocity
// -R w sin(wt) changes sign: at 0 deg and 180 deg (right and left of the circle); Y (R w cos(wt)) at 90 and
// 270 deg (top and bottom). While stuck, the reversing axis stays at its extreme while the setpoint already
// returns: the axis lags behind its setpoint (tracking error e = x_d - x has the sign of the new velocity), and
// since at those points the reversing axis is the radial direction and it stays at the extreme, the point lies
// OUTSIDE the commanded path: the radial error spikes outward (the reversal spikes of a ballbar plot). Checked
// against the same run without Coulomb friction: the difference in radius is an outward spike within 15 deg after
// each of the four reversal points, and negligible elsewhere.
TEST(Circle, CoulombFrictionGivesQuadrantGlitchesAtTheReversals) {
  const core::Machine with = drives::test::only_axes(drives::test::mikron(), {"X", "Y"});
  ASSERT_GT(with.axes[0].drive->coulomb_Nm, 0.0);
  const core::Machine without = xy_without_coulomb();
  for (double feed : {1000.0, 3000.0}) {
    const Circle c{10.0, feed / 60};
    const CircleRun a = run_circle(with, c, 2), b = run_circle(without, c, 2);
    struct Reversal {
      double deg;
      int axis;
      double new_velocity_sign;
    };
    const Reversal reversals[] = {{0, 0, -1}, {90, 1, -1}, {180, 0, +1}, {270, 1, +1}};
    double elsewhere = 0.0;
    double peaks[4] = {0, 0, 0, 0};
    double peak_deg[4] = {0, 0, 0, 0};
    double lag_sign[4] = {0, 0, 0, 0};
    for (Eigen::Index k = a.first; k < a.last; ++k) {
      const double dr = radius_at(a.response, k) - radius_at(b.response, k);
      const double deg = angle_deg(c, k);
      bool near = false;
      for (int i = 0; i < 4; ++i) {
        double after = deg - reversals[i].deg;
        if (after < -180) after += 360;
        if (after >= 0.0 && after <= 15.0) {
          near = true;
          if (std::abs(dr) > std::abs(peaks[i])) {
            peaks[i] = dr;
            peak_deg[i] = deg;
            const int ax = reversals[i].axis;
            lag_sign[i] = (a.setpoints.position(k, ax) - a.response.position(k, ax)) * reversals[i].new_velocity_sign;
          }
        }
      }
      if (!near) elsewhere = std::max(elsewhere, std::abs(dr));
    }
    for (int i = 0; i < 4; ++i) {
      std::printf(
          "circle R 10 mm at %g m/min: %s reversal at %g deg: radial glitch %+.3e mm at %.1f deg "
          "(elsewhere |dr| <= %.1e mm), reversing axis %s\n",
          feed / 1000, reversals[i].axis == 0 ? "X" : "Y", reversals[i].deg, peaks[i], peak_deg[i], elsewhere,
          lag_sign[i] > 0 ? "lags" : "leads");
      EXPECT_GT(peaks[i], 0.0) << "the glitch must point outward at " << reversals[i].deg << " deg";
      EXPECT_GT(peaks[i], 1e-4) << "a glitch of at least 0.1 um at " << reversals[i].deg << " deg";
      EXPECT_GT(peaks[i], 5.0 * elsewhere) << reversals[i].deg;
      EXPECT_GT(lag_sign[i], 0.0) << "the reversing axis lags behind its setpoint at " << reversals[i].deg;
    }
  }
}

}  // namespace
}  // namespace vmsim::methods
