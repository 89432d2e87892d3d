// Profiles: the ISO 21920-2 parameters against a sine whose parameters are known in closed form, the Gaussian
// profile filter's transmission against ISO 16610-21's formula, and a measured profile registered along a line
// across a surface against the shift, offset and tilt it was made with.
#include "core/error.hpp"
#include "metrology/profile.hpp"
#include "core/units.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace vmsim;

namespace {

using vmsim::core::units::kPi;

metrology::LineScan sine(double amplitude, double wavelength, double dx, int n, double phase = 0.0) {
  metrology::LineScan p;
  p.dx_mm = dx;
  p.z_mm.resize(n);
  for (int i = 0; i < n; ++i) p.z_mm[i] = amplitude * std::sin(2 * kPi * i * dx / wavelength + phase);
  return p;
}

}  // namespace

// A sine of amplitude A over whole periods: Ra = 2A/pi, Rq = A/sqrt(2), Rsk = 0, Rku = 3/2, and with a sample on
// every crest and trough (a period of 4k samples) Rp = Rv = A, Rz = Rt = 2A in every section holding a period.
TEST(ProfileParameters, SineInClosedForm) {
  const double A = 2e-3, lambda = 0.08, dx = 0.0001;  // 800 samples a period
  const metrology::LineScan p = sine(A, lambda, dx, 800 * 10);
  const auto r = metrology::profile_parameters(p, 5);
  EXPECT_EQ(r.points, 8000u);
  EXPECT_NEAR(r.Ra_mm, 2 * A / kPi, 1e-5 * A);  // the mean of |sin| sampled 800 times a period: O(1/800^2) off
  EXPECT_NEAR(r.Rq_mm, A / std::sqrt(2.0), 1e-12 * A);
  EXPECT_NEAR(r.Rsk, 0.0, 1e-9);
  EXPECT_NEAR(r.Rku, 1.5, 1e-9);
  EXPECT_NEAR(r.Rp_mm, A, 1e-12);
  EXPECT_NEAR(r.Rv_mm, A, 1e-12);
  EXPECT_NEAR(r.Rz_mm, 2 * A, 1e-12);
  EXPECT_NEAR(r.Rt_mm, 2 * A, 1e-12);
  EXPECT_EQ(r.sections, 5);
  EXPECT_NEAR(r.section_length_mm, 0.16, 1e-12);
  EXPECT_NEAR(r.evaluation_length_mm, 0.8, 1e-12);
}

// The least-squares line is removed exactly, and leaves the sine's parameters (a cosine over whole periods is
// orthogonal to the line, so the fit takes nothing of it).
TEST(ProfileParameters, FormRemovalLeavesTheTexture) {
  metrology::LineScan p = sine(1e-3, 0.05, 0.0001, 500 * 6, kPi / 2);
  for (Eigen::Index i = 0; i < p.size(); ++i) p.z_mm[i] += 0.3 + 0.02 * p.x(i);
  metrology::ProfileEvaluation how;
  how.level = 1;
  const auto r = metrology::evaluate_profile(p, how).parameters;
  EXPECT_NEAR(r.Rq_mm, 1e-3 / std::sqrt(2.0), 1e-9);
  EXPECT_NEAR(r.Rku, 1.5, 1e-6);
  how.level = 0;  // the mean line only: the slope is part of the "roughness" and Rq grows
  EXPECT_GT(metrology::evaluate_profile(p, how).parameters.Rq_mm, 1e-3);
}

// ISO 16610-21: the Gaussian mean line transmits a sine of wavelength lambda with a0/a = exp(-pi (alpha lc /
// lambda)^2), 50 % at the cut-off. Checked in the middle of a long profile, at three wavelengths.
TEST(ProfileFilter, GaussianTransmissionIsIso16610_21) {
  const double lc = 0.8, dx = 0.0005, alpha = std::sqrt(std::log(2.0) / kPi);
  for (const double lambda : {0.4, 0.8, 2.5}) {
    const metrology::LineScan p = sine(1.0, lambda, dx, static_cast<int>(12 / dx));
    const metrology::LineScan m = metrology::gaussian_profile_mean_line(p, lc);
    double amp = 0;
    for (Eigen::Index i = p.size() / 3; i < 2 * p.size() / 3; ++i) amp = std::max(amp, std::abs(m.z_mm[i]));
    const double expect = std::exp(-kPi * std::pow(alpha * lc / lambda, 2));
    EXPECT_NEAR(amp, expect, 2e-3) << "lambda " << lambda;  // the kernel's truncation at lc costs < 1e-6
  }
}

// At the ends the weights are renormalised over the points inside the window: a level profile stays level there,
// and an L-filtered profile drops half a cut-off at each end before the parameters.
TEST(ProfileFilter, EndsAndRunInRunOut) {
  metrology::LineScan p;
  p.dx_mm = 0.001;
  p.z_mm = Eigen::ArrayXd::Constant(4000, 0.25);
  p.z_mm[100] = NAN;
  const auto m = metrology::gaussian_profile_mean_line(p, 0.8);
  EXPECT_NEAR(m.z_mm[0], 0.25, 1e-15);
  EXPECT_NEAR(m.z_mm[3999], 0.25, 1e-15);
  EXPECT_TRUE(std::isnan(m.z_mm[100]));
  metrology::ProfileEvaluation how;
  how.level = 1;
  how.filters.push_back({'L', 0.8});
  const metrology::LineScan s = sine(1e-3, 0.1, 0.001, 4000);
  const auto e = metrology::evaluate_profile(s, how);
  EXPECT_NEAR(e.profile.x0_mm, 0.4, 1e-9);
  EXPECT_NEAR(e.profile.x(e.profile.size() - 1), 3.599, 1e-9);
  EXPECT_EQ(e.parameters.sections, 4);  // 3.2 mm evaluated in sections of lc = 0.8 mm
  EXPECT_NEAR(e.parameters.section_length_mm, 0.8, 1e-12);
  // A 0.1 mm wavelength passes the 0.8 mm L-filter whole: Rq of the roughness is the sine's.
  EXPECT_NEAR(e.parameters.Rq_mm, 1e-3 / std::sqrt(2.0), 1e-3 * 1e-3);
  how.filters = {{'L', 2.5}};
  EXPECT_THROW(metrology::evaluate_profile(s, how), core::Error);  // 4 mm is shorter than two cut-offs of 2.5 mm
}

TEST(ProfileLine, AcrossAPlaneIsExact) {
  core::HeightGrid g;
  g.x0_mm = -1, g.y0_mm = 2, g.dx_mm = 0.01, g.dy_mm = 0.02;
  g.z_mm.resize(101, 201);
  for (Eigen::Index j = 0; j < g.ny(); ++j)
    for (Eigen::Index i = 0; i < g.nx(); ++i) g.z_mm(j, i) = 0.1 * g.x(i) - 0.05 * g.y(j) + 3;
  const auto p = metrology::line_across(g, -0.5, 2.5, 0.5, 3.5, 0.005);
  EXPECT_EQ(p.size(), static_cast<Eigen::Index>(std::floor(std::sqrt(2.0) / 0.005)) + 1);
  for (Eigen::Index k = 0; k < p.size(); ++k) {
    const double s = p.x(k), x = -0.5 + s / std::sqrt(2.0), y = 2.5 + s / std::sqrt(2.0);
    EXPECT_NEAR(p.z_mm[k], 0.1 * x - 0.05 * y + 3, 1e-12) << k;
  }
  const auto off = metrology::line_across(g, 5, 5, 6, 6, 0.01);  // entirely off the grid
  EXPECT_TRUE(off.z_mm.isNaN().all());
}

// A stylus profile taken along a line across a surface with a known shift along the line, a datum offset and a
// tilt, plus noise: the registration finds them, and the deviation is the noise.
TEST(ProfileCompare, RecoversShiftOffsetAndTilt) {
  core::HeightGrid g;
  g.dx_mm = g.dy_mm = 0.005;
  g.z_mm.resize(401, 801);
  // Scallops of 0.25 mm along x, a slower wave, and a mark: a profile along x has features to register on.
  const auto surf = [](double x, double y) {
    return 0.004 * std::cos(2 * kPi * x / 0.25) + 0.01 * std::sin(2 * kPi * x / 1.7) -
           0.006 * std::exp(-std::pow((x - 2.2) / 0.1, 2)) + 0.001 * y;
  };
  for (Eigen::Index j = 0; j < g.ny(); ++j)
    for (Eigen::Index i = 0; i < g.nx(); ++i) g.z_mm(j, i) = surf(g.x(i), g.y(j));
  // The line y = 1 from x = 0.2 to 3.8; the stylus trace starts 0.6123 mm along it, 2.5 mm long, 0.5 um steps.
  const double shift = 0.6123, offset = 0.035, tilt = 2e-4;
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.0002);
  metrology::LineScan m;
  m.x0_mm = 10.0;  // the instrument's own x origin
  m.dx_mm = 0.0005;
  m.z_mm.resize(5000);
  for (Eigen::Index i = 0; i < m.size(); ++i) {
    const double s = shift + static_cast<double>(i) * m.dx_mm;
    m.z_mm[i] = surf(0.2 + s, 1.0) + offset + tilt * s + noise(rng);
  }
  const auto c = metrology::compare_profile(m, g, 0.2, 1.0, 3.8, 1.0);
  EXPECT_NEAR(c.shift_mm, shift, 0.0005);
  // The noise (0.2 um on 5000 points over 2.5 mm) leaves the fitted tilt a standard error of 3.9e-6 and the offset
  // at the centre one of 2.8e-6 mm: held to 4 of them.
  EXPECT_NEAR(c.tilt, tilt, 1.6e-5);
  EXPECT_NEAR(c.offset_mm, offset + tilt * c.s_centre_mm, 1.2e-5);  // the fit's offset is at s = s_centre
  EXPECT_EQ(c.points, 5000u);
  EXPECT_NEAR(c.rms_mm, 0.0002, 0.00002);  // the noise, plus bilinear interpolation error far below it
  // Without registration, the profile is taken where it says it is: at the line's start, with its own datum.
  metrology::ProfileAlignmentOptions none;
  none.align = false;
  const auto d = metrology::compare_profile(m, g, 0.2, 1.0, 3.8, 1.0, none);
  EXPECT_EQ(d.shift_mm, 0.0);
  EXPECT_GT(d.rms_mm, 0.02);
}
