// NURBS curves and the interpolator's feed ceiling. References: the exact rational quadratic circle (radius,
// curvature, length in closed form), finite differences of the curve for its derivatives, the curve itself for the
// quintic chain, and the machine's limits by finite differences of the setpoints for the interpolator.
#include "core/error.hpp"
#include "motion/interp.hpp"
#include "core/machine.hpp"
#include "motion/nurbs.hpp"
#include "core/units.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

using namespace vmsim::core;
using namespace vmsim::motion;

namespace {

using vmsim::core::units::kPi;

// The full circle of radius r about c as a rational quadratic NURBS: 9 control points on the square around it,
// corner weights sqrt(2)/2 (The NURBS Book, ex. 7.2).
NurbsCurve circle(double r, Eigen::Vector3d c = Eigen::Vector3d::Zero()) {
  NurbsCurve n;
  n.degree = 2;
  const double w = std::sqrt(0.5);
  const double xs[9] = {1, 1, 0, -1, -1, -1, 0, 1, 1}, ys[9] = {0, 1, 1, 1, 0, -1, -1, -1, 0};
  for (int i = 0; i < 9; ++i) {
    n.points.push_back(c + r * Eigen::Vector3d(xs[i], ys[i], 0));
    n.weights.push_back(i % 2 ? w : 1.0);
  }
  n.knots = {0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1};
  n.source = "circle";
  return n;
}

std::string shared(const std::string& rel) { return std::string(VMSIM_SHARED_DIR) + "/" + rel; }

NurbsCurve butterfly() {
  return read_nurbs_csv(std::string(VMSIM_SOURCE_DIR) + "/parts/feedplan/butterfly_nurbs_control_points.csv",
                        std::string(VMSIM_SOURCE_DIR) + "/parts/feedplan/butterfly_nurbs_knots.csv", 3);
}

}  // namespace

TEST(Nurbs, CircleHasItsRadiusCurvatureAndLength) {
  const double r = 7.5;
  const NurbsCurve c = circle(r, {1, 2, 0});
  for (int i = 0; i <= 1000; ++i) {
    const double u = i / 1000.0;
    const ArcJet j = arc_jet(nurbs_derivs(c, u));
    EXPECT_NEAR((j.p - Eigen::Vector3d(1, 2, 0)).norm(), r, 1e-12);
    EXPECT_NEAR(j.t.norm(), 1.0, 1e-12);
    EXPECT_NEAR(j.k.norm(), 1.0 / r, 1e-10);
    // The curvature vector points to the centre; its derivative along the circle is -t / r^2.
    EXPECT_NEAR((j.p + j.k * r * r - Eigen::Vector3d(1, 2, 0)).norm(), 0.0, 1e-9);
    EXPECT_NEAR((j.dk + j.t / (r * r)).norm(), 0.0, 1e-8);
  }
  const NurbsArcLength arc(c);
  EXPECT_NEAR(arc.length(), 2 * kPi * r, 1e-10);
  for (double s : {0.0, 1.0, 10.0, 23.5, 40.0, 2 * kPi * r}) EXPECT_NEAR(arc.s_at(arc.u_at(s)), s, 1e-10);
}

TEST(Nurbs, DerivativesMatchFiniteDifferences) {
  const NurbsCurve c = butterfly();
  const double h = 1e-6;
  for (double u : {0.003, 0.1, 0.17, 0.33, 0.5011, 0.72, 0.95}) {
    const NurbsDerivs d = nurbs_derivs(c, u), a = nurbs_derivs(c, u - h), b = nurbs_derivs(c, u + h);
    EXPECT_LT((d.d1 - (b.p - a.p) / (2 * h)).norm(), 1e-6 * std::max(1.0, d.d1.norm())) << u;
    EXPECT_LT((d.d2 - (b.d1 - a.d1) / (2 * h)).norm(), 1e-5 * std::max(1.0, d.d2.norm())) << u;
    EXPECT_LT((d.d3 - (b.d2 - a.d2) / (2 * h)).norm(), 1e-4 * std::max(1.0, d.d3.norm())) << u;
  }
  // The butterfly is closed: first and last control points coincide.
  EXPECT_NEAR((nurbs_derivs(c, 0.0).p - nurbs_derivs(c, 1.0).p).norm(), 0.0, 1e-12);
}

TEST(Nurbs, QuinticChainIsG2AndWithinTolerance) {
  const NurbsCurve c = butterfly();
  NurbsPathOptions o;
  o.tolerance_mm = 1e-5;
  const NurbsPath np = nurbs_to_path(c, o);
  ASSERT_GT(np.path.pieces.size(), 10u);
  EXPECT_LE(np.max_deviation_mm, o.tolerance_mm);
  const NurbsArcLength arc(c);
  EXPECT_NEAR(np.path.length, arc.length(), 1e-6 * arc.length());
  // Joints: position, unit tangent and curvature vector continuous (G2), and the curve's own values there.
  for (std::size_t i = 0; i + 1 < np.path.pieces.size(); ++i) {
    const PathPiece& a = np.path.pieces[i];
    const PathPiece& b = np.path.pieces[i + 1];
    const PathJet ja = a.jet_at_u(1.0), jb = b.jet_at_u(0.0);
    const ArcJet jc = arc_jet(nurbs_derivs(c, np.joint_u[i + 1]));
    EXPECT_LT((ja.p - jb.p).norm(), 1e-9);
    EXPECT_LT((ja.t - jb.t).norm(), 1e-9);
    EXPECT_LT((ja.k - jb.k).norm(), 1e-7 * std::max(1.0, jc.k.norm()));
    EXPECT_LT((jb.k.head<3>() - jc.k).norm(), 1e-7 * std::max(1.0, jc.k.norm()));
  }
  // Inside the pieces: distance to the curve at the same parameter, and curvature within 0.1 %.
  for (std::size_t i = 0; i < np.path.pieces.size(); i += 7) {
    const PathPiece& pc = np.path.pieces[i];
    for (int k = 1; k < 10; ++k) {
      const double t = k / 10.0;
      const double u = np.joint_u[i] + t * (np.joint_u[i + 1] - np.joint_u[i]);
      const ArcJet jc = arc_jet(nurbs_derivs(c, u));
      const PathJet jp = pc.jet_at_u(t);
      EXPECT_LT((jp.p.head<3>() - jc.p).norm(), o.tolerance_mm);
      EXPECT_LT(std::abs(jp.k.norm() - jc.k.norm()), 1e-3 * jc.k.norm() + 1e-6);
    }
  }
  // Arc-length maps between the curve and the chain are inverse to each other.
  for (double s : {0.0, 0.5, 17.3, 150.0, 300.1, arc.length()}) EXPECT_NEAR(np.curve_s(np.path_s(s)), s, 1e-9);
}

TEST(Nurbs, ReadsTheSharedButterflyAndRejectsBadFiles) {
  const std::string cp = shared("data/curves/butterfly_nurbs_control_points.csv");
  if (!std::filesystem::exists(cp)) GTEST_SKIP() << "../shared is absent";
  const NurbsCurve c = read_nurbs_csv(cp, shared("data/curves/butterfly_nurbs_knots.csv"), 3);
  EXPECT_EQ(c.points.size(), 51u);
  EXPECT_EQ(c.knots.size(), 55u);
  EXPECT_DOUBLE_EQ(c.weights[14], 5.0);
  // Degree 4 with the same knots: the sizes no longer match; the message names the file and the counts.
  try {
    (void)read_nurbs_csv(cp, shared("data/curves/butterfly_nurbs_knots.csv"), 4);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("55 knots"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("butterfly_nurbs_control_points.csv"), std::string::npos) << e.what();
  }
  const auto dir = std::filesystem::temp_directory_path() / "vmsim_nurbs_test";
  std::filesystem::create_directories(dir);
  {
    std::ofstream(dir / "cp.csv") << "# c\nindex,x,y,z,weight\n0,0,0,0,1\n1,1,0,0,-2\n2,2,1,0,1\n";
    std::ofstream(dir / "k.csv") << "index,knot\n0,0\n1,0\n2,0\n3,1\n4,1\n5,1\n";
  }
  try {
    (void)read_nurbs_csv(dir / "cp.csv", dir / "k.csv", 2);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cp.csv:4"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

// ---- the interpolator's feed ceiling and given geometry -----------------------------------------------------------

namespace {

Machine chen2016_machine() {
  return load_machine(std::string(VMSIM_SOURCE_DIR) + "/parts/feedplan/chen2016_machine.toml");
}

double worst_limit_ratio(const Setpoints& sp, const Machine& machine) {
  const AxisPeaks p = finite_difference_peaks(sp);
  double w = 0;
  for (std::size_t a = 0; a < machine.axes.size(); ++a) {
    const auto i = static_cast<Eigen::Index>(a);
    w = std::max({w, p.velocity[i] / machine.axes[a].max_velocity, p.acceleration[i] / machine.axes[a].max_acceleration,
                  p.jerk[i] / machine.axes[a].max_jerk});
  }
  return w;
}

}  // namespace

TEST(InterpFeedCeiling, LineSlowsWhereTheCeilingDipsAndKeepsTheLimits) {
  const Machine m = chen2016_machine();
  ToolPath tp;
  tp.source_path = "line";
  Move mv;
  mv.start = Vec6::Zero();
  mv.end = Vec6::Zero();
  mv.end[0] = 60;
  mv.feed_mm_per_min = 3000;
  tp.moves.push_back(mv);
  InterpOptions io;
  io.period_s = 0.004;
  const InterpResult free = interpolate(tp, m, io);
  // A dip to 10 mm/s over [25, 35] mm, v^2 linear in s between the points.
  for (double s = 0; s <= 60.0001; s += 0.25) {
    io.feed_ceiling.s_mm.push_back(s);
    io.feed_ceiling.feed_mm_per_s.push_back(s >= 25 && s <= 35 ? 10.0 : 50.0);
  }
  const InterpResult r = interpolate(tp, m, io);
  EXPECT_GT(r.stats.cycle_time_s, free.stats.cycle_time_s + 0.3);
  EXPECT_LE(worst_limit_ratio(r.setpoints, m), 1.0 + 1e-9);
  for (Eigen::Index k = 1; k < r.setpoints.samples(); ++k) {
    // The speed between two setpoints against the ceiling anywhere on that chord.
    const double s0 = r.setpoints.path_length_mm[k - 1], s1 = r.setpoints.path_length_mm[k];
    EXPECT_LE(r.setpoints.path_speed_mm_per_s[k], io.feed_ceiling.min_over(s0, s1) * (1 + 1e-6) + 1e-9) << k;
  }
  // The ceiling's own reading: v^2 linear between points.
  FeedCeiling c{{0, 10}, {10, 20}};
  EXPECT_NEAR(c.at(5), std::sqrt(250.0), 1e-12);
  EXPECT_NEAR(c.min_over(2, 8), std::sqrt(100 + 0.2 * 300), 1e-12);
  EXPECT_THROW((FeedCeiling{{0, 1}, {5, 0}}.check()), Error);
  EXPECT_THROW((FeedCeiling{{1, 1}, {5, 5}}.check()), Error);
}

TEST(InterpFeedCeiling, NurbsGeometryIsFollowedWithinTheChainAndTheLimits) {
  const Machine m = chen2016_machine();
  const NurbsCurve c = circle(20.0);
  NurbsPathOptions no;
  no.feed_mm_per_min = 3000;
  const NurbsPath np = nurbs_to_path(c, no);
  InterpOptions io;
  io.period_s = 0.004;
  io.geometry = std::make_shared<const SmoothPath>(np.path);
  const InterpResult r = interpolate(np.program, m, io);
  EXPECT_LE(worst_limit_ratio(r.setpoints, m), 1.0 + 1e-9);
  double worst = 0;
  for (Eigen::Index k = 0; k < r.setpoints.samples(); ++k)
    worst = std::max(worst, std::abs(r.setpoints.position.row(k).head<2>().norm() - 20.0));
  EXPECT_LT(worst, 2e-5);  // every setpoint on the circle (chain within 10 nm, rounding)
  EXPECT_NEAR(r.setpoints.path_length_mm[r.setpoints.samples() - 1], 2 * kPi * 20, 1e-6);
  // A geometry that does not start where the moves do is refused.
  ToolPath moved = np.program;
  moved.initial_position[0] += 1;
  moved.moves.front().start[0] += 1;
  EXPECT_THROW(interpolate(moved, m, io), Error);
}
