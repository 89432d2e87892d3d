// Checks of a drive before it runs (drives/drive_checks): the cascade's closed-loop poles from its linearised model
// against the analytic second-order loop, the stability limit against the time-domain cascade, and the findings on
// the typos of issue 18 (kv_1000_per_min = 6000 for 6, inertia_kg_m2 = 1e-9).
#include "drives/drive_checks.hpp"

#include "drives/cascade_axis.hpp"
#include "drives/linear_model.hpp"
#include "drive_test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>

namespace vmsim::drives {
namespace {

using test::mikron_x;

bool has_code(const core::Warnings& w, const std::string& code) {
  for (const auto& x : w)
    if (x.code == code) return true;
  return false;
}

// Reference: a P position loop (gain Kv) around a first-order velocity loop (bandwidth wv) has the characteristic
// polynomial s^2 + wv s + wv Kv (e.g. Ellis, Control System Design Guide, ch. 17: cascaded loops). A velocity loop
// with a P controller on a free inertia and a fast current loop is that first-order loop, wv = Kp Kt / J. With
// wv = 2000 1/s and Kv = 1000 1/s the poles are s = -1000 +- 1000j (damping 0.707). The model's current loop
// (20 kHz), back-EMF and the 20 us sampling shift them by a few per cent.
TEST(DriveChecks, ClosedLoopPolesMatchTheAnalyticSecondOrderLoop) {
  core::DriveParams p = mikron_x();
  const double wv = 2000.0, wc = 2 * M_PI * 20000.0, te = 20e-6;
  p.current_period_s = p.velocity_period_s = 1e-6;
  p.current_kp_V_per_A = p.inductance_H * wc;
  p.current_tn_s = p.inductance_H / p.resistance_ohm;
  p.velocity_kp_A_s_per_rad = p.inertia_kg_m2 * wv / p.torque_constant_Nm_per_A;
  p.velocity_tn_s = 1e9;  // no integral action: the velocity loop is first order
  p.viscous_Nm_s_per_rad = 0.0;
  p.kv_per_s = 1000.0;
  p.kf = 0.0;  // no feedforward and no delays: the plain P loop of the reference
  p.position_delay_samples = p.feedforward_delay_samples = 0;
  const LinearAxisModel model(p, te);
  const Eigen::VectorXcd z = model.closed_loop_poles();
  // The dominant pair: the poles with the smallest |s| that are complex.
  std::complex<double> best;
  double best_err = 1e300;
  for (Eigen::Index k = 0; k < z.size(); ++k) {
    const std::complex<double> s = std::log(z[k]) / te;
    const double err = std::abs(s - std::complex<double>(-1000.0, 1000.0));
    if (err < best_err) best_err = err, best = s;
  }
  EXPECT_NEAR(best.real(), -1000.0, 50.0) << best;
  EXPECT_NEAR(best.imag(), 1000.0, 50.0) << best;
  const DriveStability d = drive_stability(p, te);
  EXPECT_LT(d.pole_radius, 1.0);
  EXPECT_NEAR(d.min_damping, 0.707, 0.05);  // the pair is the least damped
  // Low-frequency following error of that loop: E = s (s + wv) / (s^2 + wv s + wv Kv) = s / Kv + s^2 (1/(wv Kv) -
  // 1/Kv^2) + ...: c1 = 1 ms (the sampled loop x[k+1] = x[k] + Te Kv e[k] has the same ramp error v / Kv), and
  // c2 = 1/(2e6) - 1e-6 = -0.5e-6 s^2.
  EXPECT_NEAR(d.lag_s, 1e-3, 0.01e-3);
  EXPECT_NEAR(d.lag_s2, -0.5e-6, 0.05e-6);
}

// The Mikron's drives (Duong et al.'s C1 gains, which that paper ran on the real machine) are stable, with a gain
// margin well over 2, and give no finding.
TEST(DriveChecks, TheMikronDrivesAreStableAndQuiet) {
  const core::Machine m = test::mikron();
  for (const auto& ax : m.axes) {
    if (!ax.drive) continue;
    const DriveStability d = drive_stability(*ax.drive, 1e-3);
    EXPECT_LT(d.pole_radius, 1.0) << ax.name;
    EXPECT_GT(d.gain_margin, 2.0) << ax.name;
    EXPECT_NEAR(d.kv_te, 0.1, 1e-12) << ax.name;
    const core::Warnings w = check_drive(*ax.drive, 1e-3, ax.name, "m.toml");
    EXPECT_TRUE(w.empty()) << ax.name << ": " << (w.empty() ? "" : w[0].message);
    // Steady ramp error of a P loop with velocity feedforward: (1 - KF) v / Kv plus the position path's delay
    // (1 Te) against the feedforward's (1 Te), plus the inner loop's lag: c1 at least (1 - KF) / Kv.
    EXPECT_GT(d.lag_s, (1 - ax.drive->kf) / ax.drive->kv_per_s * 0.99) << ax.name;
    EXPECT_LT(d.lag_s, (1 - ax.drive->kf) / ax.drive->kv_per_s * 1.3) << ax.name;
  }
}

// The stability limit the model gives, against the time-domain cascade: a small step (no saturation) decays at 0.8
// times the critical Kv and grows at 1.25 times it.
TEST(DriveChecks, GainMarginAgreesWithTheTimeDomainCascade) {
  core::DriveParams p = mikron_x();
  p.coulomb_Nm = 0.0;  // the linear model has no Coulomb friction
  const double te = 1e-3;
  const DriveStability d = drive_stability(p, te);
  ASSERT_TRUE(std::isfinite(d.gain_margin));
  auto late_amplitude = [&](double factor) {
    core::DriveParams q = p;
    q.kv_per_s = p.kv_per_s * d.gain_margin * factor;
    q.kf = 0.0;
    CascadeAxis ax(q, te, core::AxisKind::Linear);
    ax.reset(0.0);
    AxisCommand c;
    c.position = 1e-4;  // 0.1 um step: far from the current limit
    double late = 0;
    for (int k = 0; k < 4000; ++k) {
      const double x = ax.step(c).position;
      if (k >= 3000) late = std::max(late, std::abs(x - c.position));
    }
    return late;
  };
  EXPECT_LT(late_amplitude(0.8), 1e-6);
  EXPECT_GT(late_amplitude(1.25), 1e-4);
}

// Issue 18's typos: Kv 6000 instead of 6 (m/min)/mm makes the position loop unstable; an inertia of 1e-9 kg m^2
// the velocity loop. Both are Invalid, with a message naming the axis and the key.
TEST(DriveChecks, TyposAreUnstableAndNamed) {
  core::DriveParams p = mikron_x();
  p.kv_per_s = 6000.0 * 1000.0 / 60.0;
  core::Warnings w = check_drive(p, 1e-3, "X", "m.toml");
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].code, "position_loop_unstable");
  EXPECT_EQ(w[0].severity, core::Warning::Severity::Invalid);
  EXPECT_NE(w[0].message.find("axis X"), std::string::npos) << w[0].message;
  EXPECT_NE(w[0].message.find("kv_1000_per_min = 6000"), std::string::npos) << w[0].message;

  p = mikron_x();
  p.inertia_kg_m2 = 1e-9;
  w = check_drive(p, 1e-3, "Y", "m.toml");
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].code, "drive_unstable");
  EXPECT_NE(w[0].message.find("inertia_kg_m2"), std::string::npos) << w[0].message;
  EXPECT_STREQ(core::verdict(w), "invalid");
}

// A gain just under the limit: stable, but a finding (gain margin under 2).
TEST(DriveChecks, SmallGainMarginIsAWarning) {
  core::DriveParams p = mikron_x();
  const double gm = drive_stability(p, 1e-3).gain_margin;
  p.kv_per_s *= gm * 0.7;
  const core::Warnings w = check_drive(p, 1e-3, "X", "m.toml");
  EXPECT_TRUE(has_code(w, "small_gain_margin"));
  EXPECT_STREQ(core::verdict(w), "warnings");
}

}  // namespace
}  // namespace vmsim::drives
