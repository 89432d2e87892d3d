// core/arc: the frame of a programmed arc against analytic geometry (quarter circles, the three planes' orientation,
// helix length sqrt((r phi)^2 + h^2)), against LinuxCNC's rules for full circles and turns (posemath's pmCircleInit
// and the interpreter's find_turn: start == end is a whole turn, an end on the start's ray is a whole turn, |P| - 1
// further turns), against an independent numerical integration (a spiral's length as a 2-million-chord polyline, its
// tangent as a central difference), and the chord count against the sag it promises.
#include "core/arc.hpp"

#include "core/error.hpp"
#include "core/units.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <string>

namespace {

using Eigen::Vector3d;
using vmsim::core::ArcFrame;
using vmsim::core::ArcPlane;
using vmsim::core::MotionKind;
using vmsim::core::Move;
using vmsim::core::Vec6;

using vmsim::core::units::kPi;

Vec6 v6(double x, double y, double z, double a = 0, double b = 0, double c = 0) {
  Vec6 v;
  v << x, y, z, a, b, c;
  return v;
}

Move arc(ArcPlane plane, const Vec6& start, const Vec6& end, Eigen::Vector2d centre, int rotation) {
  Move m;
  m.kind = MotionKind::Arc;
  m.plane = plane;
  m.start = start;
  m.end = end;
  m.centre_mm = centre;
  m.rotation = rotation;
  m.source_line = 12;
  return m;
}

}  // namespace

TEST(ArcFrame, QuarterCircleBothWays) {
  const Move ccw = arc(ArcPlane::XY, v6(10, 0, 0), v6(0, 10, 0), {0, 0}, 1);
  const ArcFrame f = vmsim::core::arc_frame(ccw);
  EXPECT_EQ(f.axis1, vmsim::core::kX);
  EXPECT_EQ(f.axis2, vmsim::core::kY);
  EXPECT_EQ(f.normal, vmsim::core::kZ);
  EXPECT_DOUBLE_EQ(f.start_angle_rad, 0.0);
  EXPECT_DOUBLE_EQ(f.sweep_rad, kPi / 2);
  EXPECT_FALSE(f.full_circle);
  EXPECT_NEAR((f.point_at(0.5).head<3>() - Vector3d(10 / std::sqrt(2), 10 / std::sqrt(2), 0)).norm(), 0, 1e-12);
  EXPECT_NEAR(f.length_mm(), 5 * kPi, 1e-12);
  // Clockwise between the same points: the other three quarters, through (0, -10).
  const ArcFrame g = vmsim::core::arc_frame(arc(ArcPlane::XY, v6(10, 0, 0), v6(0, 10, 0), {0, 0}, -1));
  EXPECT_DOUBLE_EQ(g.sweep_rad, -1.5 * kPi);
  EXPECT_NEAR((g.point_at(1.0 / 3).head<3>() - Vector3d(0, -10, 0)).norm(), 0, 1e-12);
}

TEST(ArcFrame, PlanesAreRightHanded) {
  // Counter-clockwise about the plane's normal: the tangent at the start is normal x (start - centre), for each plane
  // (G17: about +Z, G18: about +Y with Z first, G19: about +X with Y first; RS274/NGC, NIST IR 6556 fig. 3).
  for (const ArcPlane plane : {ArcPlane::XY, ArcPlane::ZX, ArcPlane::YZ}) {
    const vmsim::core::PlaneAxes ax = vmsim::core::plane_axes(plane);
    Vec6 s = Vec6::Zero(), e = Vec6::Zero();
    s[ax.axis1] = 10;  // at angle 0 about the centre (0, 0)
    e[ax.axis2] = 10;  // at angle pi/2
    for (const int rot : {1, -1}) {
      const ArcFrame f = vmsim::core::arc_frame(arc(plane, s, e, {0, 0}, rot));
      const Vector3d n = Vector3d::Unit(ax.normal), r = s.head<3>();
      const Vector3d t = f.tangent_at(0).normalized();
      EXPECT_NEAR((t - (rot > 0 ? 1.0 : -1.0) * n.cross(r).normalized()).norm(), 0, 1e-12) << int(plane) << " " << rot;
      EXPECT_NEAR(n.cross(Vector3d::Unit(ax.axis1)).dot(Vector3d::Unit(ax.axis2)), 1, 0);
    }
  }
}

TEST(ArcFrame, FullCirclesAndTurnsAsLinuxCnc) {
  // start == end: a whole turn each way; |rotation| - 1 more turns.
  const Vec6 p = v6(3, 4, 1);
  for (const int rot : {1, -1, 3, -3}) {
    const ArcFrame f = vmsim::core::arc_frame(arc(ArcPlane::XY, p, p, {0, 0}, rot));
    EXPECT_TRUE(f.full_circle);
    EXPECT_EQ(f.extra_turns, std::abs(rot) - 1);
    EXPECT_DOUBLE_EQ(f.sweep_rad, (rot > 0 ? 1 : -1) * 2 * kPi * std::abs(rot));
  }
  // An end within 1e-9 of max(1 mm, r) of the start in the plane closes the circle too (a CL file's rounding of the
  // same point), ahead of or behind the start.
  for (const double d : {+2e-8, -2e-8}) {
    const Vec6 e = v6(50 * std::cos(d / 50), 50 * std::sin(d / 50), 0);
    const ArcFrame f = vmsim::core::arc_frame(arc(ArcPlane::XY, v6(50, 0, 0), e, {0, 0}, 1));
    EXPECT_TRUE(f.full_circle);
    EXPECT_DOUBLE_EQ(f.sweep_rad, 2 * kPi);
  }
  // Farther than that it is the short arc it says (a 1 um arc at r = 50 mm).
  const ArcFrame tiny = vmsim::core::arc_frame(
      arc(ArcPlane::XY, v6(50, 0, 0), v6(50 * std::cos(2e-8), 50 * std::sin(2e-8), 0), {0, 0}, 1));
  EXPECT_NEAR(tiny.sweep_rad, 2e-8, 1e-15);
  // A spiral whose end lies on its start's ray (radii within a reader's tolerance): a whole turn, as pmCircleInit makes
  // it (the cross product of the radius vectors is nil: angle 2 pi) and find_turn (end angle <= start angle: + 2 pi).
  const ArcFrame ray = vmsim::core::arc_frame(arc(ArcPlane::XY, v6(10, 0, 0), v6(10.0004, 0, 0), {0, 0}, 1));
  EXPECT_FALSE(ray.full_circle);
  EXPECT_DOUBLE_EQ(ray.sweep_rad, 2 * kPi);
  const ArcFrame ray2 = vmsim::core::arc_frame(arc(ArcPlane::ZX, v6(0, 0, 7), v6(0, 0, 7.0003), {0, 0}, -2));
  EXPECT_DOUBLE_EQ(ray2.sweep_rad, -4 * kPi);
}

TEST(ArcFrame, PointsAreExactAtTheEndsAndLinearInTheOtherAxes) {
  // A helix in the YZ plane (about X) with A and C turning: X, A and C move linearly with the swept angle.
  const Vec6 s = v6(5, 0, 20, 0.1, 0, -0.3), e = v6(-3, 20, 0, 0.4, 0, 0.2);
  const ArcFrame f = vmsim::core::arc_frame(arc(ArcPlane::YZ, s, e, {0, 0}, 2));
  EXPECT_EQ(f.point_at(0), s);
  EXPECT_EQ(f.point_at(1), e);
  EXPECT_EQ(f.point_at(-0.5), s);
  EXPECT_EQ(f.point_at(1.5), e);
  for (const double t : {0.1, 0.5, 0.9}) {
    const Vec6 p = f.point_at(t);
    for (const int i : {0, 3, 4, 5}) EXPECT_NEAR(p[i], s[i] + t * (e[i] - s[i]), 1e-14);
    EXPECT_NEAR(std::hypot(p[1], p[2]), 20, 1e-12);
  }
  // From angle pi/2 (on +Z) counter-clockwise to angle 0 (on +Y): three quarters, and one more turn (rotation 2).
  EXPECT_DOUBLE_EQ(f.sweep_rad, 3.5 * kPi);
  // Helix length: sqrt((r sweep)^2 + h^2).
  EXPECT_NEAR(f.length_mm(), std::hypot(20 * f.sweep_rad, 8.0), 1e-12);
}

TEST(ArcFrame, SpiralLengthAndTangentAgainstNumericalIntegration) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  for (int k = 0; k < 6; ++k) {
    const double r0 = 1 + 50 * u(rng), r1 = r0 * (0.3 + 1.4 * u(rng)), a0 = 2 * kPi * u(rng), a1 = 2 * kPi * u(rng);
    const Vec6 s = v6(r0 * std::cos(a0), r0 * std::sin(a0), 0),
               e = v6(r1 * std::cos(a1), r1 * std::sin(a1), 30 * u(rng) - 15);
    const int rot = (k % 2 ? 1 : -1) * (1 + k % 3);
    const ArcFrame f = vmsim::core::arc_frame(arc(ArcPlane::XY, s, e, {0, 0}, rot));
    // The reference: a polyline of 2 million chords (error ~ L (d phi)^2 / 24, below 1e-11 relative here).
    const int n = 2000000;
    double len = 0;
    Vector3d prev = f.point_at(0).head<3>();
    for (int i = 1; i <= n; ++i) {
      const Vector3d p = f.point_at(double(i) / n).head<3>();
      len += (p - prev).norm();
      prev = p;
    }
    EXPECT_NEAR(f.length_mm(), len, 1e-9 * len) << k;
    for (const double t : {0.2, 0.6}) {
      const double h = 1e-6;
      const Vector3d d = (f.point_at(t + h).head<3>() - f.point_at(t - h).head<3>()) / (2 * h);
      EXPECT_NEAR((f.tangent_at(t) - d).norm(), 0, 1e-6 * d.norm()) << k;
    }
  }
}

TEST(ArcFrame, ChordsKeepTheirSag) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  for (int k = 0; k < 200; ++k) {
    const double r = 0.5 + 80 * u(rng), a0 = 2 * kPi * u(rng), a1 = 2 * kPi * u(rng),
                 sag = std::pow(10, -4 + 3 * u(rng));
    const Vec6 s = v6(r * std::cos(a0), r * std::sin(a0), 0), e = v6(r * std::cos(a1), r * std::sin(a1), 0);
    const ArcFrame f = vmsim::core::arc_frame(arc(ArcPlane::XY, s, e, {0, 0}, k % 2 ? 2 : -1));
    const int n = f.chords(sag);
    // The worst point of each chord's arc is its middle: measured, not taken from the formula.
    double worst = 0;
    for (int i = 0; i < n; ++i) {
      const Vector3d a = f.point_at(double(i) / n).head<3>(), b = f.point_at(double(i + 1) / n).head<3>();
      const Vector3d mid = f.point_at((i + 0.5) / n).head<3>();
      worst = std::max(worst, (mid - 0.5 * (a + b)).norm());
    }
    EXPECT_LE(worst, sag * (1 + 1e-9)) << k;
    // Not needlessly many: one chord fewer would break the sag.
    if (n > 1) {
      EXPECT_GT(r * (1 - std::cos(std::abs(f.sweep_rad) / (n - 1) / 2)), sag * (1 - 1e-9)) << k;
    }
    // Pieces of at most a quarter turn.
    const int q = f.chords(sag, kPi / 2);
    EXPECT_EQ(q, static_cast<int>(std::ceil(std::abs(f.sweep_rad) / (kPi / 2) - 1e-12))) << k;
  }
  // Radii within the sag: half turns (a chord of a half circle stays within r of it), never a full circle in one.
  const ArcFrame small = vmsim::core::arc_frame(arc(ArcPlane::XY, v6(1e-4, 0, 0), v6(1e-4, 0, 0), {0, 0}, 1));
  EXPECT_EQ(small.chords(1e-3), 2);
}

TEST(ArcFrame, ErrorsNameTheProgramLine) {
  const Vec6 p = v6(10, 0, 0);
  auto message = [](const Move& m) {
    try {
      (void)vmsim::core::arc_frame(m, "part.ngc");
    } catch (const vmsim::core::Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message(arc(ArcPlane::XY, p, v6(0, 0, 0), {0, 0}, 1)), "part.ngc:12: arc with zero radius or no direction");
  EXPECT_EQ(message(arc(ArcPlane::XY, v6(10, 0, 5), v6(10, 0, 0), {10, 0}, 1)),
            "part.ngc:12: arc with zero radius or no direction");
  EXPECT_EQ(message(arc(ArcPlane::XY, p, v6(0, 10, 0), {0, 0}, 0)),
            "part.ngc:12: arc with zero radius or no direction");
}
