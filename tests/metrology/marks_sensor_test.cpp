// Marks along and across the tool path, the lay of a raster-milled surface, profiles, and the confocal sensor
// model (its spot's transfer, noise, flank dropouts, repeatability).
#include "core/error.hpp"
#include "metrology/areal.hpp"
#include "metrology/marks.hpp"
#include "metrology/mesh_distance.hpp"
#include "metrology/sensor.hpp"
#include "core/units.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace vmsim;

namespace {
using vmsim::core::units::kPi;
core::HeightGrid sensor_grid(int nx, int ny, double h) {
  core::HeightGrid g;
  g.dx_mm = g.dy_mm = h;
  g.z_mm = core::HeightArray::Zero(ny, nx);
  return g;
}
}  // namespace

// A dip elongated along a path at 30 degrees: sigma 1 mm along, 0.1 mm across; the half-depth region spans the
// full widths at half depth, 2 sigma sqrt(2 ln 2).
TEST(Marks, AlongAndAcrossTheGivenPathDirection) {
  core::HeightGrid dev = sensor_grid(801, 601, 0.01);
  const double th = kPi / 6, c = std::cos(th), s = std::sin(th);
  for (int j = 0; j < 601; ++j)
    for (int i = 0; i < 801; ++i) {
      const double x = dev.x(i) - 4, y = dev.y(j) - 3, a = c * x + s * y, b = -s * x + c * y;
      dev.z_mm(j, i) = -0.01 * std::exp(-0.5 * (a * a / 1.0 + b * b / 0.01));
    }
  const auto marks = metrology::find_marks(dev, 1e-3, 10, th);
  ASSERT_EQ(marks.size(), 1u);
  const double fwhm = 2 * std::sqrt(2 * std::log(2.0));
  EXPECT_NEAR(marks[0].along_mm, fwhm * 1.0, 0.02);
  EXPECT_NEAR(marks[0].width_mm, fwhm * 0.1, 0.02);
  EXPECT_NEAR(marks[0].direction_rad, th, 1e-12);
  EXPECT_NEAR(marks[0].depth_mm, 0.01, 1e-6);
  // The profile across the path through the deepest point is the Gaussian of sigma 0.1.
  const auto p = metrology::profile(dev, marks[0].x_mm, marks[0].y_mm, th + kPi / 2, 0.3, 0.01);
  ASSERT_EQ(p.s_mm.size(), 61);
  for (Eigen::Index k = 0; k < p.s_mm.size(); ++k)
    EXPECT_NEAR(p.z_mm[k], -0.01 * std::exp(-0.5 * p.s_mm[k] * p.s_mm[k] / 0.01), 1.5e-5);  // bilinear: h^2 z'' / 8
}

TEST(Lay, ScallopRidgesRunAlongTheFeed) {
  for (const double th : {0.0, 0.4, -1.2, kPi / 2}) {
    core::HeightGrid g = sensor_grid(300, 300, 0.01);
    for (int j = 0; j < 300; ++j)
      for (int i = 0; i < 300; ++i) {
        const double across = -std::sin(th) * g.x(i) + std::cos(th) * g.y(j);
        g.z_mm(j, i) = 0.004 * std::cos(2 * kPi * across / 0.25);  // stepover 0.25 mm
      }
    const auto lay = metrology::lay_of(g);
    EXPECT_NEAR(std::remainder(lay.direction_rad - th, kPi), 0, 5e-3) << th;  // partial periods at the edges
    EXPECT_GT(lay.anisotropy, 0.99);
  }
}

TEST(Sensor, SpotHalvesItsHalfAmplitudeWavelength) {
  metrology::SensorOptions o;
  o.step_mm = 0.002, o.spot_mm = 0.02, o.noise_mm = 0, o.max_slope_deg = 89;
  metrology::SensorReport r;
  core::HeightGrid pred = sensor_grid(2001, 5, 0.001);
  (void)metrology::simulate_scan(pred, o, &r);  // for the report's wavelength
  const double L = r.half_amplitude_wavelength_mm;
  EXPECT_NEAR(L, 0.04532, 1e-5);  // pi sigma sqrt(2 / ln 2), sigma = 0.02 / 2.355
  for (int j = 0; j < 5; ++j)
    for (int i = 0; i < 2001; ++i) pred.z_mm(j, i) = 0.001 * std::sin(2 * kPi * pred.x(i) / L);
  const auto scan = metrology::simulate_scan(pred, o, &r);
  double amp = 0;
  for (Eigen::Index i = 200; i < scan.nx() - 200; ++i) amp = std::max(amp, std::abs(scan.z_mm(2, i)));
  EXPECT_NEAR(amp, 0.0005, 0.00002);
}

TEST(Sensor, NoiseDropoutsOnSteepFlanksAndRepeatability) {
  core::HeightGrid pred = sensor_grid(1001, 201, 0.002);
  // A V-groove with 45 degree flanks in a flat face.
  for (int j = 0; j < 201; ++j)
    for (int i = 0; i < 1001; ++i) pred.z_mm(j, i) = -std::max(0.0, 0.1 - std::abs(pred.x(i) - 1.0));
  metrology::SensorOptions o;
  o.step_mm = 0.004, o.spot_mm = 0.003, o.noise_mm = 0.0002, o.max_slope_deg = 30, o.seed = 9;
  metrology::SensorReport r;
  const auto a = metrology::simulate_scan(pred, o, &r);
  // Flanks: x in [0.9, 1.1] minus the spot's rounding at the edges and the tip.
  EXPECT_NEAR(static_cast<double>(r.slope_dropouts) / static_cast<double>(a.ny()), 0.2 / 0.004, 4);
  EXPECT_EQ(r.outside, 0u);
  // Noise on the flat part.
  core::HeightGrid flat = a;
  for (Eigen::Index j = 0; j < a.ny(); ++j)
    for (Eigen::Index i = 0; i < a.nx(); ++i)
      if (std::abs(a.x(i) - 1.0) < 0.15) flat.z_mm(j, i) = NAN;
  EXPECT_NEAR(metrology::areal_parameters(flat).Sq_mm, 0.0002, 0.00001);
  const auto b = metrology::simulate_scan(pred, o);
  EXPECT_TRUE(((a.z_mm == b.z_mm) || (a.z_mm.isNaN() && b.z_mm.isNaN())).all());
}

TEST(MeshDistance, RasterizedTopOfAGridMeshIsTheGrid) {
  core::HeightGrid g = sensor_grid(41, 31, 0.05);
  for (int j = 0; j < 31; ++j)
    for (int i = 0; i < 41; ++i) g.z_mm(j, i) = 0.1 * std::sin(g.x(i)) + 0.05 * g.y(j);
  const auto r = metrology::rasterize_top(metrology::grid_surface_mesh(g), 0.05);
  ASSERT_EQ(r.nx(), 41);
  ASSERT_EQ(r.ny(), 31);
  EXPECT_LT((r.z_mm - g.z_mm).abs().maxCoeff(), 1e-12);
}
