// Deviation along the reference's normal (metrology::normal_deviation) against analytic surfaces: tilted planes and
// a cylinder offset by a known distance along their normals, whose exact normal distance is known in closed form;
// the vertical figure keeps its meaning (the height difference); marks carry both and the slope.
#include "core/error.hpp"
#include "metrology/marks.hpp"
#include "core/units.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>

using namespace vmsim;

namespace {
using vmsim::core::units::kPi;

core::HeightGrid normal_sample(int nx, int ny, double h, const std::function<double(double, double)>& z) {
  core::HeightGrid g;
  g.dx_mm = g.dy_mm = h;
  g.z_mm = core::HeightArray::Zero(ny, nx);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) g.z_mm(j, i) = z(g.x(i), g.y(j));
  return g;
}
}  // namespace

// A plane of slope theta (falling along the azimuth 30 deg, so both gradients count), and the same plane moved
// 5 um along its normal into the material (an overcut): its height is 5 um / cos(theta) lower everywhere. The normal
// deviation is -5 um at every node (first order is exact on a plane), the vertical one -5 um / cos(theta).
TEST(NormalDeviation, TiltedPlaneOffsetAlongItsNormalIsTheOffsetWhateverTheSlope) {
  const double d = 0.005, h = 0.05, az = kPi / 6;
  for (const double deg : {0.0, 30.0, 60.0, 80.0}) {
    const double t = std::tan(deg * kPi / 180), c = std::cos(deg * kPi / 180);
    auto plane = [&](double x, double y) { return t * (std::cos(az) * x + std::sin(az) * y); };
    const core::HeightGrid ref = normal_sample(41, 31, h, plane);
    const core::HeightGrid surf = normal_sample(41, 31, h, [&](double x, double y) { return plane(x, y) - d / c; });
    const core::HeightGrid vert = metrology::deviation(surf, ref);
    const metrology::Slope slope = metrology::slope_of(ref);
    const core::HeightGrid normal = metrology::normal_deviation(vert, slope);
    for (Eigen::Index k = 0; k < normal.z_mm.size(); ++k) {
      EXPECT_NEAR(normal.z_mm.data()[k], -d, 1e-9) << deg << " deg, node " << k;
      EXPECT_NEAR(vert.z_mm.data()[k], -d / c, 1e-9) << deg << " deg, node " << k;
      EXPECT_NEAR(slope.slope_rad.z_mm.data()[k], deg * kPi / 180, 1e-9) << deg << " deg, node " << k;
    }
    // The marks: one region, depth along the normal, the vertical figure and the slope beside it; steep beyond 60.
    std::vector<metrology::Mark> marks = metrology::find_marks(normal, 1e-3);
    metrology::add_vertical(marks, vert, slope);
    ASSERT_EQ(marks.size(), 1u) << deg;
    EXPECT_NEAR(marks[0].depth_mm, d, 1e-9);
    EXPECT_NEAR(marks[0].depth_vertical_mm, d / c, 1e-9);
    EXPECT_NEAR(marks[0].slope_rad * 180 / kPi, deg, 1e-6);
    EXPECT_TRUE(marks[0].overcut);
    if (deg == metrology::kSteepWallSlopeDeg) continue;  // on the limit itself, rounding decides
    EXPECT_EQ(marks[0].steep_wall, deg > metrology::kSteepWallSlopeDeg) << deg;
    const metrology::SteepWalls walls = metrology::steep_walls(slope);
    EXPECT_EQ(walls.fraction, deg > metrology::kSteepWallSlopeDeg ? 1.0 : 0.0) << deg;
    EXPECT_EQ(walls.nodes, deg > metrology::kSteepWallSlopeDeg ? 41u * 31u : 0u) << deg;
  }
}

// On a flat reference the normal deviation is the vertical one, bit for bit (every flat part's outputs unchanged).
TEST(NormalDeviation, FlatReferenceLeavesTheVerticalDeviationBitIdentical) {
  const core::HeightGrid ref = normal_sample(30, 20, 0.1, [](double, double) { return 2.5; });
  const core::HeightGrid surf =
      normal_sample(30, 20, 0.1, [](double x, double y) { return 2.5 - 0.003 * std::sin(x * y); });
  const core::HeightGrid vert = metrology::deviation(surf, ref);
  const core::HeightGrid normal = metrology::normal_deviation(vert, metrology::slope_of(ref));
  for (Eigen::Index k = 0; k < vert.z_mm.size(); ++k) EXPECT_EQ(normal.z_mm.data()[k], vert.z_mm.data()[k]);
}

// A cylinder wall: the reference is the upper half of a cylinder of radius R = 10 mm lying along y (slopes 0 to 90
// deg across x), the surface the same cylinder cut d = 10 um deeper (radius R - d): the exact normal distance is
// -d everywhere. First order gives d - d^2 tan^2 / (2R) (the curvature term) plus the central difference's error
// d h^2 sin^2 / (2 R^2 cos^4); both stated in metrology/marks.hpp and checked here up to 80 deg. The vertical figure
// is the height difference, 5.7 d at 80 deg.
TEST(NormalDeviation, CylinderWallCutDeeperByAKnownOffsetGivesTheOffsetUpTo80Degrees) {
  const double R = 10, d = 0.01, h = 0.02;
  const int nx = static_cast<int>(std::floor(R / h));  // x from 0 to just under R: slope 0 .. 88.9 deg
  auto cyl = [](double r) { return [r](double x, double) { return x < r ? std::sqrt(r * r - x * x) : NAN; }; };
  const core::HeightGrid ref = normal_sample(nx, 3, h, cyl(R));
  const core::HeightGrid surf = normal_sample(nx, 3, h, cyl(R - d));
  const core::HeightGrid vert = metrology::deviation(surf, ref);
  const metrology::Slope slope = metrology::slope_of(ref);
  const core::HeightGrid normal = metrology::normal_deviation(vert, slope);
  int checked = 0, steep = 0;
  for (int i = 1; i + 1 < nx; ++i) {
    const double th = std::asin(ref.x(i) / R);
    if (th > 80 * kPi / 180) break;
    const double s = std::sin(th), c = std::cos(th), t = std::tan(th);
    // The leading terms reach 0.993 of the error at worst (computed alongside); 5 % for the higher-order ones.
    const double bound = 1.05 * (d * d * t * t / (2 * R) + d * h * h * s * s / (2 * R * R * c * c * c * c)) + 1e-9;
    EXPECT_NEAR(normal.z_mm(1, i), -d, bound) << "x " << ref.x(i) << " slope " << th * 180 / kPi;
    EXPECT_NEAR(slope.slope_rad.z_mm(1, i), th, 2e-3) << "x " << ref.x(i);
    EXPECT_NEAR(vert.z_mm(1, i), std::sqrt((R - d) * (R - d) - ref.x(i) * ref.x(i)) - ref.z_mm(1, i), 1e-12);
    ++checked, steep += th > 60 * kPi / 180;
  }
  EXPECT_GT(checked, 400);
  EXPECT_GT(steep, 50);
  // At 80 deg: within 2 % of d along the normal, while the vertical figure is 5.7 d.
  const int i80 = static_cast<int>(std::floor(R * std::sin(80 * kPi / 180) / h));
  EXPECT_NEAR(normal.z_mm(1, i80), -d, 0.02 * d);
  EXPECT_GT(-vert.z_mm(1, i80), 5.5 * d);
}

// A wall the spacing does not resolve: a step of H = 2 mm between two nodes, the surface's wall moved 10 um
// sideways across a node. Vertically that node is H off; along the normal the first-order figure is bounded by
// about the spacing (|dz| cos(slope) with the secant slope H / 2h: 2h |dz| / H), as metrology/marks.hpp states.
TEST(NormalDeviation, UnresolvedWallIsBoundedByTheSpacing) {
  const double H = 2, h = 0.05, e = 0.01;
  const double wall = 1.0 + 0.5 * e;  // node x = 1.0 lies between the two walls
  const core::HeightGrid ref = normal_sample(41, 3, h, [&](double x, double) { return x < wall ? H : 0.0; });
  const core::HeightGrid surf = normal_sample(41, 3, h, [&](double x, double) { return x < wall - e ? H : 0.0; });
  const core::HeightGrid vert = metrology::deviation(surf, ref);
  const metrology::Slope slope = metrology::slope_of(ref);
  const core::HeightGrid normal = metrology::normal_deviation(vert, slope);
  const int i = 20;  // x = 1.0
  ASSERT_NEAR(ref.x(i), 1.0, 1e-12);
  EXPECT_NEAR(vert.z_mm(1, i), -H, 1e-12);
  EXPECT_LE(std::abs(normal.z_mm(1, i)), 2 * h);
  EXPECT_GT(std::abs(normal.z_mm(1, i)), e);  // the lateral error itself is not recovered below the spacing
  EXPECT_GT(slope.slope_rad.z_mm(1, i), 85 * kPi / 180);
  // The part mesh's bound between nodes on this wall is the step itself.
  EXPECT_DOUBLE_EQ(metrology::wall_step_max_mm(surf), H);
  EXPECT_EQ(metrology::wall_step_max_mm(normal_sample(41, 3, h, [](double x, double) { return 0.5 * x; })), 0.0);
}

TEST(NormalDeviation, RefusesGridsThatDiffer) {
  const core::HeightGrid a = normal_sample(10, 10, 0.1, [](double, double) { return 0.0; });
  const core::HeightGrid b = normal_sample(11, 10, 0.1, [](double, double) { return 0.0; });
  EXPECT_THROW(metrology::normal_deviation(a, metrology::slope_of(b)), core::Error);
}
