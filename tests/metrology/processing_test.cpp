// Form removal, the ISO 16610-61 Gaussian filter, outlier masking and the ISO 25178-2 areal parameters, each
// against a closed form: planes and polynomials recovered exactly, the filter's 50 % transmission at the cut-off,
// the parameters of sinusoids and of a rectangular groove.
#include "core/error.hpp"
#include "metrology/areal.hpp"
#include "metrology/filter.hpp"
#include "metrology/form.hpp"
#include "core/units.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace vmsim;

namespace {
using vmsim::core::units::kPi;

core::HeightGrid processing_grid(int nx, int ny, double dx, double dy, double x0 = 0, double y0 = 0) {
  core::HeightGrid g;
  g.x0_mm = x0, g.y0_mm = y0, g.dx_mm = dx, g.dy_mm = dy;
  g.z_mm = core::HeightArray::Zero(ny, nx);
  return g;
}
}  // namespace

// z = A sin(2 pi x / L), two whole periods, 1000 nodes per period (so the peaks are nodes).
TEST(Areal, SinusoidAlongXEqualsClosedForms) {
  const double A = 0.004, L = 0.2;
  core::HeightGrid g = processing_grid(2000, 9, L / 1000, 0.01);
  for (int j = 0; j < 9; ++j)
    for (int i = 0; i < 2000; ++i) g.z_mm(j, i) = A * std::sin(2 * kPi * g.x(i) / L);
  const auto p = metrology::areal_parameters(g);
  EXPECT_NEAR(p.mean_mm, 0, 1e-15);
  // On N nodes per period the mean of |sin| is (2/N) cot(pi/N) (-> 2/pi as N grows).
  const int N = 1000;
  EXPECT_NEAR(p.Sa_mm, A * 2.0 / N / std::tan(kPi / N), 1e-15);
  EXPECT_NEAR(p.Sa_mm, 2 * A / kPi, 1e-8);
  EXPECT_NEAR(p.Sq_mm, A / std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(p.Sp_mm, A, 1e-15);
  EXPECT_NEAR(p.Sv_mm, A, 1e-15);
  EXPECT_NEAR(p.Sz_mm, 2 * A, 1e-15);
  EXPECT_NEAR(p.Ssk, 0, 1e-9);
  EXPECT_NEAR(p.Sku, 1.5, 1e-9);
  // Slopes: the surface's slope amplitude is a = A k. Central differences see a' = A sin(k h) / h exactly (within
  // (k h)^2 / 6 = 7e-6 of a here); with a' the closed forms hold to rounding, with a to that discretisation error.
  const double h = g.dx_mm, kk = 2 * kPi / L, a = A * kk, ad = A * std::sin(kk * h) / h;
  EXPECT_NEAR(p.Sdq, ad / std::sqrt(2.0), 1e-6 * a);  // 1e-6: one-sided differences at the two edge columns
  EXPECT_NEAR(p.Sdq, a / std::sqrt(2.0), 1e-5 * a);
  // Sdr = 100 (mean sqrt(1 + a^2 cos^2) - 1) = 100 ((2/pi) sqrt(1 + a^2) E(a / sqrt(1 + a^2)) - 1), E the complete
  // elliptic integral of the second kind.
  const auto sdr_of = [](double s) {
    return 100 * (2 / kPi * std::sqrt(1 + s * s) * std::comp_ellint_2(s / std::sqrt(1 + s * s)) - 1);
  };
  EXPECT_NEAR(p.Sdr_percent, sdr_of(ad), 1e-6 * sdr_of(a));
  EXPECT_NEAR(p.Sdr_percent, sdr_of(a), 2e-5 * sdr_of(a));
  std::printf("sinusoid A %.3g mm, L %.3g mm: Sdq %.9f (closed form %.9f), Sdr %.9f %% (closed form %.9f %%)\n", A, L,
              p.Sdq, a / std::sqrt(2.0), p.Sdr_percent, sdr_of(a));
}

// z = A sin(kx x) sin(ky y): Sa = 4A/pi^2, Sq = A/2, Sku = 9/4, Sdq = A sqrt(kx^2 + ky^2) / 2.
TEST(Areal, EggCrateEqualsClosedForms) {
  const double A = 0.002, Lx = 0.1, Ly = 0.05;
  core::HeightGrid g = processing_grid(1000, 1000, Lx / 500, Ly / 500);
  for (int j = 0; j < 1000; ++j)
    for (int i = 0; i < 1000; ++i) g.z_mm(j, i) = A * std::sin(2 * kPi * g.x(i) / Lx) * std::sin(2 * kPi * g.y(j) / Ly);
  const auto p = metrology::areal_parameters(g);
  EXPECT_NEAR(p.Sa_mm, A * (2.0 / 500 / std::tan(kPi / 500)) * (2.0 / 500 / std::tan(kPi / 500)), 1e-15);
  EXPECT_NEAR(p.Sa_mm, 4 * A / (kPi * kPi), 3e-5 * A);
  EXPECT_NEAR(p.Sq_mm, A / 2, 1e-12);
  EXPECT_NEAR(p.Ssk, 0, 1e-9);
  EXPECT_NEAR(p.Sku, 9.0 / 4.0, 1e-9);
  EXPECT_NEAR(p.Sp_mm, A, 1e-15);
  const double kx = 2 * kPi / Lx, ky = 2 * kPi / Ly;
  const double ax = std::sin(kx * g.dx_mm) / g.dx_mm, ay = std::sin(ky * g.dy_mm) / g.dy_mm;  // central differences
  EXPECT_NEAR(p.Sdq, A * std::hypot(ax, ay) / 2, 1e-6 * A * std::hypot(kx, ky));
  EXPECT_NEAR(p.Sdq, A * std::hypot(kx, ky) / 2, 1e-4 * A * std::hypot(kx, ky) / 2);
}

// A flat plate with a rectangular groove of depth d over a fraction p of the nodes: heights 0 (1 - p) and -d (p).
TEST(Areal, RectangularGrooveEqualsClosedForms) {
  const double d = 0.02;
  core::HeightGrid g = processing_grid(200, 50, 0.01, 0.01);
  for (int j = 0; j < 50; ++j)
    for (int i = 60; i < 90; ++i) g.z_mm(j, i) = -d;
  const double p = 30.0 / 200.0;
  const auto r = metrology::areal_parameters(g);
  EXPECT_NEAR(r.mean_mm, -p * d, 1e-15);
  EXPECT_NEAR(r.Sa_mm, 2 * d * p * (1 - p), 1e-15);
  EXPECT_NEAR(r.Sq_mm, d * std::sqrt(p * (1 - p)), 1e-15);
  EXPECT_NEAR(r.Sp_mm, p * d, 1e-15);
  EXPECT_NEAR(r.Sv_mm, (1 - p) * d, 1e-15);
  EXPECT_NEAR(r.Sz_mm, d, 1e-15);
  EXPECT_NEAR(r.Ssk, (2 * p - 1) / std::sqrt(p * (1 - p)), 1e-12);
  EXPECT_NEAR(r.Sku, (p * p * p + (1 - p) * (1 - p) * (1 - p)) / (p * (1 - p)), 1e-12);
  // The walls: central differences see d / (2 dx) at the 2 x 2 nodes beside them, per row.
  const double s = d / (2 * 0.01);
  EXPECT_NEAR(r.Sdq, std::sqrt(4 * s * s / 200.0), 1e-12);
}

TEST(Areal, InvalidPointsTakeNoPart) {
  core::HeightGrid g = processing_grid(10, 10, 1, 1);
  g.z_mm.setConstant(1.0);
  g.z_mm(3, 3) = NAN;
  g.z_mm(4, 4) = NAN;
  const auto p = metrology::areal_parameters(g);
  EXPECT_EQ(p.points, 98u);
  EXPECT_EQ(p.Sq_mm, 0.0);
  EXPECT_TRUE(std::isnan(p.Ssk));
  g.z_mm.setConstant(NAN);
  EXPECT_THROW(metrology::areal_parameters(g), core::Error);
}

TEST(Form, PlaneIsRecoveredAndRemoved) {
  core::HeightGrid g = processing_grid(300, 200, 0.01, 0.02, -1.0, 2.0);
  for (int j = 0; j < 200; ++j)
    for (int i = 0; i < 300; ++i) g.z_mm(j, i) = 0.3 + 0.002 * g.x(i) - 0.0015 * g.y(j);
  g.z_mm(5, 7) = NAN;
  metrology::FormFit f;
  const auto r = metrology::remove_form(g, 1, &f);
  EXPECT_NEAR(f.slope_x, 0.002, 1e-14);
  EXPECT_NEAR(f.slope_y, -0.0015, 1e-14);
  EXPECT_NEAR(f.rms_residual_mm, 0, 1e-13);
  EXPECT_TRUE(std::isnan(r.z_mm(5, 7)));
  EXPECT_NEAR(r.z_mm.isNaN().select(0, r.z_mm).abs().maxCoeff(), 0, 1e-13);
  EXPECT_EQ(f.points, 300u * 200u - 1);
}

TEST(Form, CubicPolynomialIsRemovedExactly) {
  core::HeightGrid g = processing_grid(120, 90, 0.05, 0.05, 3.0, -1.0);
  const auto poly = [](double x, double y) {
    return 0.1 - 0.02 * x + 0.03 * y + 0.004 * x * x - 0.001 * x * y + 0.0005 * x * x * y - 0.0002 * y * y * y;
  };
  for (int j = 0; j < 90; ++j)
    for (int i = 0; i < 120; ++i) g.z_mm(j, i) = poly(g.x(i), g.y(j));
  metrology::FormFit f;
  const auto r = metrology::remove_form(g, 3, &f);
  EXPECT_NEAR(r.z_mm.abs().maxCoeff(), 0, 1e-12);
  EXPECT_NEAR(f.evaluate(4.2, 1.1), poly(4.2, 1.1), 1e-12);
  // A plane leaves the curvature.
  const auto r1 = metrology::remove_form(g, 1);
  EXPECT_GT(r1.z_mm.abs().maxCoeff(), 1e-3);
}

TEST(Form, TooFewPointsIsAClearError) {
  core::HeightGrid g = processing_grid(5, 5, 1, 1);
  g.z_mm.setConstant(NAN);
  g.z_mm(0, 0) = 1, g.z_mm(1, 1) = 2;
  EXPECT_THROW(metrology::remove_form(g, 1), core::Error);
  for (int i = 0; i < 5; ++i) g.z_mm(2, i) = 1;  // all points on two lines: a plane is determined
  g.z_mm(0, 0) = NAN, g.z_mm(1, 1) = NAN;
  EXPECT_THROW(metrology::remove_form(g, 1), core::Error);  // one line only
}

// ISO 16610-61: a sinusoid of wavelength lc keeps 50 % of its amplitude in the mean surface; lc/2 keeps 1/16.
TEST(GaussianFilter, TransmissionAtTheCutoff) {
  const double lc = 0.8, h = 0.005;
  for (const double L : {lc, lc / 2, 4 * lc}) {
    core::HeightGrid g = processing_grid(2001, 3, h, h);
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 2001; ++i) g.z_mm(j, i) = std::sin(2 * kPi * g.x(i) / L);
    const auto m = metrology::gaussian_mean_surface(g, lc);
    // Amplitude in the middle, more than lc from both ends.
    double amp = 0;
    for (int i = 400; i < 1600; ++i) amp = std::max(amp, std::abs(m.z_mm(1, i)));
    const double alpha = std::sqrt(std::log(2.0) / kPi);
    const double expected = std::exp(-kPi * std::pow(alpha * lc / L, 2));
    EXPECT_NEAR(amp, expected, 2e-4) << "wavelength " << L;
  }
}

TEST(GaussianFilter, ConstantStaysConstantUpToEdgesAndHoles) {
  core::HeightGrid g = processing_grid(300, 200, 0.01, 0.01);
  g.z_mm.setConstant(0.25);
  for (int j = 50; j < 70; ++j)
    for (int i = 100; i < 130; ++i) g.z_mm(j, i) = NAN;
  const auto m = metrology::gaussian_mean_surface(g, 0.25);
  EXPECT_TRUE(std::isnan(m.z_mm(60, 110)));  // invalid stays invalid, never filled
  EXPECT_NEAR(m.z_mm.isNaN().select(0.25, m.z_mm).maxCoeff(), 0.25, 1e-15);
  EXPECT_NEAR(m.z_mm.isNaN().select(0.25, m.z_mm).minCoeff(), 0.25, 1e-15);
  const auto hp = metrology::gaussian_highpass(g, 0.25);
  EXPECT_NEAR(hp.z_mm.isNaN().select(0, hp.z_mm).abs().maxCoeff(), 0, 1e-15);
}

TEST(Outliers, SpikesAreMaskedAndCounted) {
  core::HeightGrid g = processing_grid(200, 150, 0.005, 0.005);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0, 1e-4);
  for (int j = 0; j < 150; ++j)
    for (int i = 0; i < 200; ++i) g.z_mm(j, i) = 0.01 * std::sin(2 * kPi * g.x(i) / 0.3) + noise(rng);
  const int spikes[5][2] = {
      {10, 10}, {50, 120}, {149, 100}, {75, 75}, {0, 190}};  // two on edges (corners are not judged)
  for (const auto& s : spikes) g.z_mm(s[0], s[1]) += (s[0] % 2 ? 0.05 : -0.05);
  const auto r = metrology::mask_outliers(g);
  EXPECT_EQ(r.masked, 5u);
  for (const auto& s : spikes) EXPECT_TRUE(std::isnan(g.z_mm(s[0], s[1])));
  // The departures scatter a little more than the noise (the predictions are noisy too).
  EXPECT_GT(r.sigma_mm, 1e-4);
  EXPECT_LT(r.sigma_mm, 1.6e-4);
}
