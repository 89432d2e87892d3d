// The surface commands' library calls on synthetic surfaces whose answers are known: compare_surfaces (what
// `vmsim compare` runs) on a scan of an analytic part taken through a known rigid placement, with a known dent,
// noise and spikes; compare_profile_to_surface on a sine profile with a known shift; analyse_surface and plan_scan
// (`vmsim stats`, `vmsim measure`) against closed forms. References: the placement, dent and spikes put into the
// scan here; Sq = A / sqrt(2) and Ra = 2 A / pi of a sine of amplitude A (ISO 25178-2, ISO 21920-2 definitions).
#include "core/error.hpp"
#include "metrology/compare.hpp"
#include "metrology/mesh_distance.hpp"
#include "metrology/processing.hpp"
#include "metrology/scan_plan.hpp"
#include "core/units.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

using namespace vmsim;

namespace {

using vmsim::core::units::kPi;
constexpr double kDentX = 2.2, kDentY = 1.4, kDentDepth = 0.010;  // mm, in the part's frame

// Cusps of a raster along x (the lay: 0 rad), bumps that pin x and y, a tilt.
double compared_part(double x, double y) {
  return 0.004 * std::sin(2 * kPi * y / 0.25) + 0.01 * std::sin(2 * kPi * x / 1.7) * std::cos(2 * kPi * y / 2.3) +
         0.002 * x - 0.001 * y;
}
double dent(double x, double y) {
  return -kDentDepth * std::exp(-std::pow((x - kDentX) / 0.08, 2) - std::pow((y - kDentY) / 0.15, 2));
}

core::HeightGrid sample(double x0, double y0, double h, int nx, int ny, double (*f)(double, double)) {
  core::HeightGrid g;
  g.x0_mm = x0, g.y0_mm = y0, g.dx_mm = h, g.dy_mm = h;
  g.z_mm.resize(ny, nx);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) g.z_mm(j, i) = f(g.x(i), g.y(j));
  return g;
}

// The scan in its own frame: at each node the height of the part point P (part + dent) whose image under T^-1
// lies above it (Newton on the analytic surface), plus noise; `spikes` nodes get +0.2 mm.
core::HeightGrid make_scan(const metrology::RigidTransform& T, double noise, std::set<std::pair<int, int>>& spikes) {
  const metrology::RigidTransform inv = T.inverse();
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n(0, noise);
  core::HeightGrid s;
  s.x0_mm = 0.3, s.y0_mm = 0.3, s.dx_mm = 0.01, s.dy_mm = 0.01;
  s.z_mm.resize(241, 341);
  std::uniform_int_distribution<int> ui(5, 335), uj(5, 235);
  while (spikes.size() < 20) spikes.insert({uj(rng), ui(rng)});
  for (int j = 0; j < s.ny(); ++j)
    for (int i = 0; i < s.nx(); ++i) {
      const double xs = s.x(i), ys = s.y(j);
      Eigen::Vector3d P = T.apply(Eigen::Vector3d(xs, ys, 0));
      for (int it = 0; it < 50; ++it) {
        P.z() = compared_part(P.x(), P.y()) + dent(P.x(), P.y());
        const Eigen::Vector3d p = inv.apply(P);
        const Eigen::Vector2d e(xs - p.x(), ys - p.y());
        if (e.norm() < 1e-13) break;
        P.head<2>() += T.R.topLeftCorner<2, 2>() * e;
      }
      s.z_mm(j, i) = inv.apply(P).z() + n(rng) + (spikes.count({j, i}) ? 0.2 : 0.0);
    }
  return s;
}

const metrology::RigidTransform kPlacement =
    metrology::RigidTransform::from_xyz_rxyz(0.021, -0.013, 0.003, 2e-4, -3e-4, 1.5e-3);

void expect_transform(const metrology::RigidTransform& a, const metrology::RigidTransform& b,
                      const core::HeightGrid& s) {
  double worst = 0;
  for (double x : {s.x0_mm, s.x(s.nx() - 1)})
    for (double y : {s.y0_mm, s.y(s.ny() - 1)})
      worst = std::max(worst, (a.apply({x, y, 0}) - b.apply({x, y, 0})).norm());
  EXPECT_LT(worst, 1e-3) << "mm at the scan's corners";
  EXPECT_LT(Eigen::AngleAxisd(a.R * b.R.transpose()).angle(), 1e-4);
}

TEST(CompareSurfaces, RecoversThePlacementTheDentAndTheSpikes) {
  const metrology::Prediction pred{sample(0, 0, 0.01, 401, 301, compared_part), std::nullopt};
  std::set<std::pair<int, int>> spikes;
  const core::HeightGrid scan = make_scan(kPlacement, 5e-5, spikes);
  metrology::SurfaceCompareOptions o;
  const metrology::SurfaceComparison c = metrology::compare_surfaces(scan, pred, o);

  ASSERT_TRUE(c.outliers);
  EXPECT_GE(c.outliers->masked, spikes.size());
  EXPECT_LE(c.outliers->masked, spikes.size() + 2);
  for (const auto& [j, i] : spikes) EXPECT_TRUE(std::isnan(c.scan.z_mm(j, i))) << "spike at " << j << ", " << i;
  ASSERT_TRUE(c.registration);
  expect_transform(c.transform, kPlacement, scan);

  // The deviation on the prediction's grid: noise everywhere but the dent, which is the deepest mark.
  EXPECT_EQ(c.deviation.nx(), 401);
  EXPECT_EQ(c.measured_on.ny(), 301);
  EXPECT_GT(c.stats.points, 60000u);
  EXPECT_NEAR(c.stats.min, -kDentDepth, 5e-4);
  EXPECT_LT(c.stats.max, 1e-3);
  ASSERT_FALSE(c.marks.empty());
  const metrology::Mark& m = c.marks[0];
  EXPECT_TRUE(m.overcut);
  EXPECT_NEAR(m.depth_mm, kDentDepth, 5e-4);
  EXPECT_NEAR(m.x_mm, kDentX, 0.02);
  EXPECT_NEAR(m.y_mm, kDentY, 0.02);
  EXPECT_EQ(c.path_direction_from, metrology::PathDirectionFrom::Lay);
  EXPECT_LT(std::abs(c.path_direction_rad), 0.1) << "the cusps run along x";
  EXPECT_TRUE(c.marks_in_part_mm.empty()) << "grid mode: the marks are in the prediction's frame already";

  // The profile across the path through the mark: its deviation is the mark's depth at the centre.
  ASSERT_EQ(c.mark_profiles.size(), std::min<std::size_t>(c.marks.size(), 3));
  const metrology::MarkProfile& p = c.mark_profiles[0];
  const Eigen::Index mid = p.deviation.z_mm.size() / 2;
  EXPECT_NEAR(p.deviation.s_mm[mid], 0.0, 1e-12);
  EXPECT_NEAR(p.deviation.z_mm[mid], -m.depth_mm, 1e-4);
  EXPECT_NEAR(p.measured.z_mm[mid] - p.predicted.z_mm[mid], p.deviation.z_mm[mid], 1e-9);

  // Areal parameters on the common area: the dent and the noise change Sq by little.
  EXPECT_EQ(c.measured_areal.points, c.predicted_areal.points);
  EXPECT_NEAR(c.measured_areal.Sq_mm / c.predicted_areal.Sq_mm, 1.0, 0.02);
  ASSERT_TRUE(c.measured_form);
  EXPECT_NEAR(c.measured_form->slope_x, 0.002, 5e-4) << "the part's tilt, seen through the registration";

  // Without registration, through the placement given: the same deviation.
  o.align = false;
  o.initial = kPlacement;
  const metrology::SurfaceComparison given = metrology::compare_surfaces(scan, pred, o);
  EXPECT_FALSE(given.registration);
  EXPECT_EQ(given.transform.t, kPlacement.t);
  ASSERT_FALSE(given.marks.empty());
  EXPECT_NEAR(given.marks[0].depth_mm, kDentDepth, 5e-4);
}

TEST(CompareSurfaces, AgainstAMeshTheMarksComeBackInThePartFrame) {
  const core::HeightGrid grid = sample(0, 0, 0.01, 401, 301, compared_part);
  const metrology::Prediction pred = metrology::prediction_of_mesh(metrology::grid_surface_mesh(grid), 0.01);
  ASSERT_TRUE(pred.mesh);
  EXPECT_NEAR(pred.grid.dx_mm, 0.01, 1e-12);
  std::set<std::pair<int, int>> spikes;
  const core::HeightGrid scan = make_scan(kPlacement, 5e-5, spikes);
  const metrology::SurfaceComparison c = metrology::compare_surfaces(scan, pred, {});
  expect_transform(c.transform, kPlacement, scan);
  EXPECT_EQ(c.deviation.nx(), scan.nx()) << "the distance to the mesh, on the scan's grid";
  ASSERT_FALSE(c.marks.empty());
  EXPECT_NEAR(c.marks[0].depth_mm, kDentDepth, 1e-3);  // along the normal; the dent's bottom is nearly level
  ASSERT_EQ(c.marks_in_part_mm.size(), c.marks.size());
  EXPECT_NEAR(c.marks_in_part_mm[0].x(), kDentX, 0.02);
  EXPECT_NEAR(c.marks_in_part_mm[0].y(), kDentY, 0.02);
  EXPECT_GT(std::abs(c.marks[0].x_mm - kDentX), 0.01) << "the scan frame is 21 um off the part's";
  ASSERT_FALSE(c.mark_profiles.empty());
  EXPECT_EQ(c.mark_profiles[0].predicted.z_mm.size(), 0);
}

TEST(CompareSurfaces, NoOverlapIsAnError) {
  const metrology::Prediction pred{sample(0, 0, 0.01, 101, 101, compared_part), std::nullopt};
  core::HeightGrid far = sample(50, 50, 0.01, 51, 51, compared_part);
  metrology::SurfaceCompareOptions o;
  o.align = false;
  o.outlier_sigma = 0;
  EXPECT_THROW(metrology::compare_surfaces(far, pred, o), core::Error);
}

// Incommensurate waves and a groove: no shift along the line but the true one fits.
double sine_x(double x, double) {
  return 0.003 * std::sin(2 * kPi * x / 0.2) + 0.002 * std::sin(2 * kPi * x / 0.37 + 1.0) +
         0.0015 * std::sin(2 * kPi * x * x / 1.13) - 0.01 * std::exp(-std::pow((x - 2.0) / 0.05, 2));
}

TEST(CompareProfileToSurface, ShiftOffsetAndTiltAreRemovedAndBothProfilesAgree) {
  const core::HeightGrid pred = sample(0, 0, 0.002, 2001, 11, sine_x);  // 4 mm x 0.02 mm
  // A stylus trace along y = 0.01 from x = 1.5, 3 mm long (its last 0.5 mm beyond the line's end at 4 mm): the
  // surface, 5 um higher and tilted by 1e-3.
  metrology::LineScan m;
  m.x0_mm = 0.0, m.dx_mm = 0.001;
  m.z_mm.resize(3001);
  for (Eigen::Index i = 0; i < m.size(); ++i) m.z_mm[i] = sine_x(1.5 + m.x(i), 0) + 0.005 + 1e-3 * m.x(i);
  metrology::ProfileEvaluation how;
  how.level = 1;
  const metrology::ProfileSurfaceComparison r =
      metrology::compare_profile_to_surface(m, pred, 0, 0.01, 4, 0.01, {}, how);
  EXPECT_NEAR(r.along.shift_mm, 1.5, 2e-4);
  EXPECT_NEAR(r.along.tilt, 1e-3, 1e-5);
  EXPECT_NEAR(r.along.offset_mm, 0.005 + 1e-3 * (r.along.s_centre_mm - 1.5), 2e-5);
  EXPECT_LT(r.along.rms_mm, 2e-5);
  // Both evaluated on the samples both cover (s up to 4 mm: 2.5 mm of the trace) after the same levelling: the
  // same profile, the same parameters.
  EXPECT_EQ(r.measured.parameters.points, r.predicted.parameters.points);
  EXPECT_NEAR(static_cast<double>(r.measured.parameters.points), 2501.0, 2.0);
  EXPECT_NEAR(r.measured.parameters.Ra_mm, r.predicted.parameters.Ra_mm, 2e-5);
  EXPECT_NEAR(r.measured.parameters.Rz_mm, r.predicted.parameters.Rz_mm, 5e-5);
}

// A cosine over whole periods: its least-squares plane is level (a sine's would lean), so the plane removed is the
// tilt.
double tilted_sine(double x, double y) { return 0.01 * x - 0.004 * y + 0.002 * std::cos(2 * kPi * x / 0.1); }

TEST(AnalyseSurface, PlaneRemovedSpikesMaskedSqOfTheSine) {
  core::HeightGrid g = sample(0, 0, 0.005, 201, 101, tilted_sine);  // 1 mm: 10 whole periods
  for (int k = 0; k < 10; ++k) g.z_mm(10 + 8 * k, 20 + 17 * k) += 0.5;
  const metrology::SurfaceAnalysis a = metrology::analyse_surface(g, {1, {}}, 6.0);
  ASSERT_TRUE(a.outliers);
  EXPECT_EQ(a.outliers->masked, 10u);
  ASSERT_TRUE(a.form);
  EXPECT_NEAR(a.form->slope_x, 0.01, 1e-4);
  EXPECT_NEAR(a.form->slope_y, -0.004, 1e-6);
  EXPECT_NEAR(a.areal.Sq_mm, 0.002 / std::sqrt(2.0), 2e-5);
  EXPECT_EQ(a.areal.points, 201u * 101u - 10u);
  // Without masking the spikes dominate; without levelling the tilt does.
  EXPECT_GT(metrology::analyse_surface(g, {1, {}}, 0).areal.Sq_mm, 0.005);
  EXPECT_FALSE(metrology::analyse_surface(g, {0, {}}, 6).form);
  // An L-filter of 0.25 mm removes the plane's long wavelengths and keeps the 0.1 mm sine nearly whole.
  core::HeightGrid clean = sample(0, 0, 0.005, 201, 101, tilted_sine);
  const double sq_l = metrology::analyse_surface(clean, {1, {{'L', 0.25}}}, 0).areal.Sq_mm;
  EXPECT_NEAR(sq_l, 0.002 / std::sqrt(2.0), 0.1 * 0.002 / std::sqrt(2.0));
}

double plane(double, double) { return 0.0; }
double two_dents(double x, double y) {
  return -0.020 * std::exp(-std::pow((x - 0.5) / 0.15, 2) - std::pow((y - 0.5) / 0.15, 2)) -
         0.005 * std::exp(-std::pow((x - 1.5) / 0.004, 2) - std::pow((y - 0.5) / 0.004, 2));
}

TEST(PlanScan, AWideDentIsResolvedANarrowOneIsNot) {
  const core::HeightGrid pred = sample(0, 0, 0.001, 2001, 1001, two_dents);
  const core::HeightGrid ref = sample(0, 0, 0.001, 2001, 1001, plane);
  metrology::SensorOptions s;
  s.step_mm = 0.02, s.spot_mm = 0.03, s.noise_mm = 1e-4;
  const metrology::ScanPlan p = metrology::plan_scan(pred, s, &ref, 1e-3);
  EXPECT_NEAR(p.scan.dx_mm, 0.02, 1e-12);
  ASSERT_TRUE(p.scan_deviation);
  EXPECT_EQ(p.scan_deviation->nx(), p.scan.nx());
  ASSERT_EQ(p.marks.size(), 2u);
  // The wide dent (0.25 mm across at half depth): seen whole. The narrow one (7 um across): averaged away by the
  // 30 um spot and missed between 20 um nodes.
  EXPECT_NEAR(p.marks[0].mark.depth_mm, 0.020, 1e-4);
  EXPECT_TRUE(p.marks[0].resolved);
  EXPECT_NEAR(p.marks[0].scan_depth_mm, 0.020, 1e-3);
  EXPECT_NEAR(p.marks[1].mark.x_mm, 1.5, 0.002);
  EXPECT_FALSE(p.marks[1].resolved);
  EXPECT_LT(p.marks[1].scan_depth_mm, 0.5 * 0.005);
  EXPECT_LT(p.scan_areal.Sdq, p.predicted_areal.Sdq) << "the spot smooths the slopes";
  EXPECT_FALSE(metrology::plan_scan(pred, s, nullptr, 1e-3).scan_deviation);
}

}  // namespace
