// The linearised frequency response of one axis (drives/linear_model) against closed-form references.
#include "drives/linear_model.hpp"

#include "core/error.hpp"
#include "tests/drives/drive_test_support.hpp"
#include "core/units.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <cstdio>
#include <numbers>

namespace vmsim::drives {
namespace {

using cd = std::complex<double>;
using vmsim::core::units::kPi;

using test::mikron_x;

// Reference: with near-ideal inner loops the cascade reduces to the sampled P loop of Duong et al. Fig. 6,
// x[k+1] = x[k] + Te (Kv (x_d[k - d] - x[k]) + KF v_d[k - d]) (the velocity command held over Te is integrated
// exactly), whose response is G(z) = z^-d (Kv Te + KF (1 - z^-1)) / (z - 1 + Kv Te). The inner loops' remaining
// lag (about 0.2 ms at 1 kHz bandwidth) is the only difference: within 1 % in magnitude and 0.02 rad in phase up
// to 20 Hz.
TEST(LinearModel, IdealInnerLoopsGiveTheSampledPLoop) {
  core::DriveParams p = test::ideal_inner_loops(mikron_x());
  for (int d : {0, 1, 3}) {
    for (double kf : {0.0, 0.5}) {
      p.position_delay_samples = p.feedforward_delay_samples = d;
      p.kf = kf;
      const double te = 1e-3, kv = p.kv_per_s;
      const LinearAxisModel model(p, te);
      for (double f : {0.1, 1.0, 5.0, 20.0}) {
        const double w = 2 * kPi * f;
        const cd z = std::exp(cd(0, w * te));
        const cd ref = std::pow(z, -d) * (kv * te + kf * (1.0 - 1.0 / z)) / (z - 1.0 + kv * te);
        for (const cd g : {model.closed_loop(w), model.closed_loop_elements(w)}) {
          EXPECT_NEAR(std::abs(g) / std::abs(ref), 1.0, 0.01) << "d " << d << " kf " << kf << " f " << f;
          EXPECT_NEAR(std::arg(g / ref), 0.0, 0.02) << "d " << d << " kf " << kf << " f " << f;
        }
      }
    }
  }
}

// Reference: a type-1 loop follows constant setpoints exactly (G(0) = 1) and the inner cascade integrates its
// velocity command: jw P_v(jw) -> 1 as w -> 0.
TEST(LinearModel, LowFrequencyLimits) {
  const LinearAxisModel model(mikron_x(), 1e-3);
  EXPECT_EQ(model.closed_loop(0.0), cd(1.0));
  EXPECT_NEAR(std::abs(model.closed_loop(1e-3) - 1.0), 0.0, 1e-4);
  EXPECT_NEAR(std::abs(model.closed_loop_elements(1e-3) - 1.0), 0.0, 1e-4);
  const cd jw_pv = cd(0, 1e-2) * model.velocity_to_position(1e-2);
  EXPECT_NEAR(std::abs(jw_pv - 1.0), 0.0, 1e-4);
  // Chen et al.'s circle model: a P loop with KF < 1 cuts inside (positive error), growing with the speed.
  const double e1 = model.circle_radial_error(10.0, 1000.0 / 60), e2 = model.circle_radial_error(10.0, 2000.0 / 60);
  EXPECT_GT(e1, 0.0);
  EXPECT_NEAR(e2 / e1, 4.0, 0.1) << "R (1 - |G|) grows as w^2 at low frequency";
}

// Reference: the two evaluations share every loop element and differ only by the inner loops' aliasing, which is
// negligible where |G| is near 1 (contouring) and grows towards the loops' bandwidths. Recorded, with bounds.
TEST(LinearModel, ElementsAndLiftedAgreeAtContouringFrequencies) {
  const LinearAxisModel model(mikron_x(), 1e-3);
  for (double f : {0.1, 1.0, 10.0, 50.0, 100.0, 300.0}) {
    const double w = 2 * kPi * f;
    const cd a = model.closed_loop(w), b = model.closed_loop_elements(w);
    std::printf("Mikron X, f %5.1f Hz: |G| lifted %.6f elements %.6f, phase %.4f / %.4f rad\n", f, std::abs(a),
                std::abs(b), std::arg(a), std::arg(b));
    if (f <= 10.0) {
      EXPECT_LT(std::abs(a - b), 1e-5) << f;
    }
    if (f <= 100.0) {
      EXPECT_LT(std::abs(a - b), 0.01) << f;
    }
  }
}

// Reference: the same nesting rule as the time-domain model.
TEST(LinearModel, RefusesPeriodsThatDoNotNest) {
  core::DriveParams p = mikron_x();
  EXPECT_THROW(LinearAxisModel(p, 0.7e-3), core::Error);
  p.velocity_period_s = 100e-6;
  EXPECT_THROW(LinearAxisModel(p, 1e-3), core::Error);
}

}  // namespace
}  // namespace vmsim::drives
