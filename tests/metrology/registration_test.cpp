// Registration against synthetic scans made from an analytic surface through a known rigid transform, with noise
// and outliers: the transform is recovered within 1 um and 1e-4 rad (the requirement); aligning on named
// reference areas ignores a machined area that departs; flat faces report the directions they leave free; the
// resampled scan lies on the prediction to the noise.
#include "core/error.hpp"
#include "metrology/register.hpp"
#include "core/units.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace vmsim;

namespace {
using vmsim::core::units::kPi;

// Bumps in x and y, a diagonal wave, a groove along y and a tilt: every rigid motion changes the picture.
double surface(double x, double y) {
  return 0.05 * std::sin(2 * kPi * x / 3.0) * std::cos(2 * kPi * y / 4.0) +
         0.02 * std::sin(2 * kPi * (x + 0.7 * y) / 2.5) - 0.03 * std::exp(-std::pow((x - 1.0) / 0.3, 2)) + 0.001 * x -
         0.0005 * y;
}

core::HeightGrid sampled_part(double x0, double y0, double h, int nx, int ny, double (*f)(double, double)) {
  core::HeightGrid g;
  g.x0_mm = x0, g.y0_mm = y0, g.dx_mm = h, g.dy_mm = h;
  g.z_mm.resize(ny, nx);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) g.z_mm(j, i) = f(g.x(i), g.y(j));
  return g;
}

// The scan in its own frame: at each scan node (x, y), the height of the surface point P with T^-1(P) above it,
// where T (scan -> part) is the true placement. Newton on the analytic surface, then noise, spikes and dropouts.
core::HeightGrid registration_scan(const metrology::RigidTransform& T, double x0, double y0, double h, int nx, int ny,
                                   double noise, unsigned seed, double (*f)(double, double),
                                   double (*extra)(double, double) = nullptr) {
  const metrology::RigidTransform inv = T.inverse();
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0, noise);
  std::uniform_real_distribution<double> u(0, 1);
  core::HeightGrid s;
  s.x0_mm = x0, s.y0_mm = y0, s.dx_mm = h, s.dy_mm = h;
  s.z_mm.resize(ny, nx);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const double xs = s.x(i), ys = s.y(j);
      Eigen::Vector3d P = T.apply(Eigen::Vector3d(xs, ys, 0));
      for (int it = 0; it < 50; ++it) {
        P.z() = f(P.x(), P.y()) + (extra ? extra(P.x(), P.y()) : 0.0);
        const Eigen::Vector3d p = inv.apply(P);
        const Eigen::Vector2d e(xs - p.x(), ys - p.y());
        if (e.norm() < 1e-13) break;
        P.head<2>() += T.R.topLeftCorner<2, 2>() * e;
      }
      double z = inv.apply(P).z() + n(rng);
      const double r = u(rng);
      if (r < 0.001) z += (u(rng) < 0.5 ? 1 : -1) * 0.2;  // spikes
      if (r > 0.997) z = NAN;                             // dropouts
      s.z_mm(j, i) = z;
    }
  return s;
}

// How far apart two transforms put the scan's points (max over the scan's corners) and their relative rotation.
void expect_close(const metrology::RigidTransform& a, const metrology::RigidTransform& b, const core::HeightGrid& s,
                  double tol_mm, double tol_rad, const char* what) {
  double worst = 0;
  for (double x : {s.x0_mm, s.x(s.nx() - 1)})
    for (double y : {s.y0_mm, s.y(s.ny() - 1)})
      for (double z : {-0.1, 0.1}) worst = std::max(worst, (a.apply({x, y, z}) - b.apply({x, y, z})).norm());
  const double angle = Eigen::AngleAxisd(a.R * b.R.transpose()).angle();
  EXPECT_LT(worst, tol_mm) << what;
  EXPECT_LT(angle, tol_rad) << what;
  std::printf("%s: transform error %.3f um at the scan's corners, %.2e rad\n", what, worst * 1e3, angle);
}

}  // namespace

TEST(Registration, KnownTransformIsRecoveredWithin1umAnd1e4rad) {
  const core::HeightGrid pred = sampled_part(-5, -5, 0.01, 1001, 1001, surface);
  const auto truth = metrology::RigidTransform::from_xyz_rxyz(0.12, -0.08, 0.3, 2e-3, -1.5e-3, 4e-3);
  const core::HeightGrid scan = registration_scan(truth, -4, -4, 0.02, 401, 401, 0.001, 11, surface);
  const auto r = metrology::register_scan(scan, pred);
  EXPECT_TRUE(r.converged);
  EXPECT_TRUE(r.weak_directions.empty());
  expect_close(r.transform, truth, scan, 1e-3, 1e-4, "Tukey, automatic initial guess");
  EXPECT_NEAR(r.robust_sigma_mm, 0.001, 0.0003);  // the noise
  EXPECT_LT(r.inliers, r.points);                 // the spikes got weight 0
  std::printf("points %zu, inliers %zu, iterations %d, rms %.3f um, initial guess: %s\n", r.points, r.inliers,
              r.iterations, r.rms_mm * 1e3, r.initial_guess.c_str());

  metrology::RegistrationOptions huber;
  huber.loss = metrology::RobustLoss::Huber;
  huber.tuning = 1.345;
  expect_close(metrology::register_scan(scan, pred, huber).transform, truth, scan, 1e-3, 1e-4, "Huber");

  // Through the transform, the scan lies on the prediction to the noise (nodes next to a spike, which the bilinear
  // resampling spreads over its cells, left out: beyond 5 sigma).
  const core::HeightGrid back = metrology::resample_scan(scan, r.transform, pred);
  double s2 = 0;
  std::size_t n = 0, covered = 0;
  for (Eigen::Index j = 0; j < pred.ny(); ++j)
    for (Eigen::Index i = 0; i < pred.nx(); ++i) {
      if (!std::isfinite(back.z_mm(j, i))) continue;
      ++covered;
      const double d = back.z_mm(j, i) - pred.z_mm(j, i);
      if (std::abs(d) < 0.005) s2 += d * d, ++n;
    }
  EXPECT_GT(covered, 600000u);  // the scan covers 8 x 8 of the prediction's 10 x 10 mm
  EXPECT_GT(static_cast<double>(n), 0.98 * static_cast<double>(covered));
  EXPECT_LT(std::sqrt(s2 / static_cast<double>(n)), 0.0012);
}

double machined_pit(double x, double y) {  // a broad overcut over most of the scan, not on the reference face
  return x > -2.0 ? -0.015 * std::exp(-std::pow((x - 1.5) / 2.5, 2) - std::pow(y / 3.0, 2)) : 0.0;
}

TEST(Registration, RegionsAlignOnTheReferenceFacesOnly) {
  const core::HeightGrid pred = sampled_part(-5, -5, 0.01, 1001, 1001, surface);
  const auto truth = metrology::RigidTransform::from_xyz_rxyz(-0.05, 0.04, -0.2, -1e-3, 2e-3, -3e-3);
  const core::HeightGrid scan = registration_scan(truth, -4.5, -4, 0.02, 426, 401, 0.001, 12, surface, machined_pit);
  metrology::RegistrationOptions o;
  o.regions.push_back({-5, -2.2, -5, 5});  // the unmachined strip
  const auto r = metrology::register_scan(scan, pred, o);
  expect_close(r.transform, truth, scan, 1e-3, 1e-4, "aligned on the reference strip");
  // On everything, the broad pit pulls the fit away: the reason the option exists.
  const auto all = metrology::register_scan(scan, pred);
  double worst = 0;
  for (double x : {scan.x0_mm, scan.x(scan.nx() - 1)})
    for (double y : {scan.y0_mm, scan.y(scan.ny() - 1)})
      worst = std::max(worst, (all.transform.apply({x, y, 0}) - truth.apply({x, y, 0})).norm());
  EXPECT_GT(worst, 2e-3);
  std::printf("aligned on everything instead: %.1f um off at the corners\n", worst * 1e3);
}

double flat(double x, double y) { return 0.3 + 0.002 * x - 0.001 * y; }

TEST(Registration, FlatFaceReportsTheFreeDirections) {
  const core::HeightGrid pred = sampled_part(-2, -2, 0.02, 201, 201, flat);
  const auto truth = metrology::RigidTransform::from_xyz_rxyz(0, 0, 0.05, 1e-3, 1e-3, 0);
  const core::HeightGrid scan = registration_scan(truth, -1.5, -1.5, 0.02, 151, 151, 0.0005, 13, flat);
  const auto r = metrology::register_scan(scan, pred);
  ASSERT_EQ(r.weak_directions.size(), 3u);
  EXPECT_NE(std::find(r.weak_directions.begin(), r.weak_directions.end(), "rotation z"), r.weak_directions.end());
  // The constrained directions still fit: the scan lies on the plane.
  EXPECT_LT(r.rms_mm, 0.001);
  EXPECT_NEAR(r.mean_mm, 0, 1e-4);
}

TEST(Registration, NoOverlapIsAClearError) {
  const core::HeightGrid pred = sampled_part(0, 0, 0.1, 11, 11, flat);
  metrology::RegistrationOptions o;
  o.initial = metrology::RigidTransform::from_xyz_rxyz(100, 100, 0, 0, 0, 0);
  EXPECT_THROW(metrology::register_scan(pred, pred, o), core::Error);
}

#include <omp.h>

// DESIGN: results must not depend on the thread count. Same bits with 1 and 3 threads.
TEST(Registration, ResultDoesNotDependOnTheThreadCount) {
  const core::HeightGrid pred = sampled_part(-3, -3, 0.02, 301, 301, surface);
  const auto truth = metrology::RigidTransform::from_xyz_rxyz(0.02, 0.01, 0.1, 1e-3, 0, 2e-3);
  const core::HeightGrid scan = registration_scan(truth, -2, -2, 0.03, 134, 134, 0.001, 21, surface);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const auto a = metrology::register_scan(scan, pred);
  omp_set_num_threads(3);
  const auto b = metrology::register_scan(scan, pred);
  omp_set_num_threads(saved);
  EXPECT_TRUE((a.transform.R.array() == b.transform.R.array()).all());
  EXPECT_TRUE((a.transform.t.array() == b.transform.t.array()).all());
  EXPECT_EQ(a.rms_mm, b.rms_mm);
}
