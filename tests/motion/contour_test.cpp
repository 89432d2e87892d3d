// Contour error tests. References: analytic distances (a point offset from a straight line by a known normal
// offset; a point at radius R + delta from a circle of radius R, sampled finely enough that the chords lie within
// 0.1 nm of the circle), the geometry of a zigzag raster (distance to the tool's own pass and its connectors,
// written out here), and a brute-force minimum over every command segment.
#include "motion/contour.hpp"
#include "core/error.hpp"
#include "core/units.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

using namespace vmsim::core;
using namespace vmsim::motion;

namespace {

constexpr double kNm = 1e-6;  // 1 nm in mm
using vmsim::core::units::kPi;

// Distance from p to the segment [a, b], written independently of contour.cpp (Eigen, parametric form).
double seg_dist(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double l2 = ab.squaredNorm();
  if (l2 == 0.0) return (p - a).norm();
  const double t = std::clamp((p - a).dot(ab) / l2, 0.0, 1.0);
  return (p - (a + t * ab)).norm();
}

Eigen::MatrixXd rows(const std::vector<Eigen::Vector3d>& v) {
  Eigen::MatrixXd m(static_cast<Eigen::Index>(v.size()), 3);
  for (std::size_t i = 0; i < v.size(); ++i) m.row(static_cast<Eigen::Index>(i)) = v[i].transpose();
  return m;
}

// A straight line at 30 degrees in the XY plane: `rest` repeated samples at the start, `n` steps of h, `rest`
// repeated samples at the end.
struct Line {
  Eigen::Vector3d o{12.0, -7.0, 3.5}, dir{std::cos(kPi / 6), std::sin(kPi / 6), 0.0};
  Eigen::Vector3d normal{-std::sin(kPi / 6), std::cos(kPi / 6), 0.0};  // +Z x dir
  double h = 0.05;
  int n = 2000, rest = 50;
  Eigen::Vector3d at(double s) const { return o + std::clamp(s, 0.0, n * h) * dir; }  // s: arc length
  Eigen::MatrixXd command() const {
    std::vector<Eigen::Vector3d> v;
    for (int i = 0; i < rest; ++i) v.push_back(at(0));
    for (int i = 0; i <= n; ++i) v.push_back(at(i * h));
    for (int i = 0; i < rest; ++i) v.push_back(at(n * h));
    return rows(v);
  }
  // Commanded arc length at sample k (held after the end).
  double s_of(double k) const { return std::clamp(k - rest, 0.0, double(n)) * h; }
};

}  // namespace

// Actual = command delayed by a fractional number of samples (the foot falls inside segments) and offset by
// alpha along the in-plane normal; 300 settling rows after the command ends. Analytic contour error: -alpha
// (E = foot - actual = -alpha n, so n.E = -alpha), to 1 nm, for every sample including the rests.
TEST(Contour, StraightLineEqualsNormalOffsetWithinOneNanometre) {
  const Line line;
  const Eigen::MatrixXd cmd = line.command();
  for (double alpha : {0.012, -0.012, 0.3, -0.0004}) {
    const double lag = 23.37;  // samples (1.17 mm along the path)
    std::vector<Eigen::Vector3d> act;
    for (Eigen::Index k = 0; k < cmd.rows() + 300; ++k)
      act.push_back(line.at(line.s_of(k - lag)) + alpha * line.normal);
    ContourOptions opt;
    opt.plane_normal = Eigen::Vector3d::UnitZ();
    const ContourError ce = contour_error(cmd, rows(act), opt);
    ASSERT_EQ(ce.signed_mm.size(), static_cast<Eigen::Index>(act.size()));
    double worst = 0.0;
    for (Eigen::Index k = 0; k < ce.signed_mm.size(); ++k) worst = std::max(worst, std::abs(ce.signed_mm[k] + alpha));
    EXPECT_LT(worst, kNm) << "alpha " << alpha;
    EXPECT_NEAR(ce.max_abs_mm, std::abs(alpha), kNm);
    EXPECT_NEAR(ce.rms_mm, std::abs(alpha), kNm);
    EXPECT_NEAR(ce.mse_um2, alpha * alpha * 1e6, 1e-6 * alpha * alpha * 1e6);
    // The foot segment holds the foot: command rows [i, i+1] around the delayed arc length.
    for (Eigen::Index k = 0; k < ce.signed_mm.size(); ++k) {
      const int i = ce.foot_segment[k];
      ASSERT_GE(i, 0);
      ASSERT_LT(i + 1, cmd.rows());
      const Eigen::Vector3d foot = line.at(line.s_of(k - lag));
      EXPECT_LT(seg_dist(foot, cmd.row(i).transpose(), cmd.row(i + 1).transpose()), kNm) << "sample " << k;
    }
  }
}

// Without a plane normal a straight path has no principal normal: the error is its size, unsigned (documented).
TEST(Contour, StraightLineWithoutPlaneNormalIsUnsigned) {
  const Line line;
  const Eigen::MatrixXd cmd = line.command();
  std::vector<Eigen::Vector3d> act;
  const Eigen::Vector3d off = 0.01 * line.dir.cross(Eigen::Vector3d(0.3, 0.2, 0.9)).normalized();
  for (Eigen::Index k = 0; k < cmd.rows(); ++k) act.push_back(line.at(line.s_of(k - 5.5)) - off);
  const ContourError ce = contour_error(cmd, rows(act));
  EXPECT_LT((ce.signed_mm - 0.01).abs().maxCoeff(), kNm);
}

namespace {

// Circle of radius R about c in the plane spanned by (e1, e2), CCW about e1 x e2; `turn` of a revolution.
struct Circle {
  Eigen::Vector3d c{5.0, -3.0, 2.0}, e1 = Eigen::Vector3d::UnitX(), e2 = Eigen::Vector3d::UnitY();
  double r = 10.0, turn = 0.9;
  int n = 20000;       // chords within r (d theta)^2 / 8 = 0.1 nm of the circle
  double sense = 1.0;  // -1: clockwise
  double theta(double k) const { return sense * turn * 2 * kPi * std::clamp(k, 0.0, double(n)) / n; }
  Eigen::Vector3d at(double k, double radius) const {
    return c + radius * (std::cos(theta(k)) * e1 + std::sin(theta(k)) * e2);
  }
  Eigen::MatrixXd command() const {
    std::vector<Eigen::Vector3d> v;
    for (int i = 0; i <= n; ++i) v.push_back(at(i, r));
    return rows(v);
  }
};

// Actual delayed by `lag` samples at radius R + delta; returns the worst |signed - expected|.
double circle_case(const Circle& circ, double delta, double lag, double expected, const ContourOptions& opt) {
  const Eigen::MatrixXd cmd = circ.command();
  std::vector<Eigen::Vector3d> act;
  for (Eigen::Index k = 0; k < cmd.rows() + 100; ++k) act.push_back(circ.at(k - lag, circ.r + delta));
  const ContourError ce = contour_error(cmd, rows(act), opt);
  return (ce.signed_mm - expected).abs().maxCoeff();
}

}  // namespace

// Circle: the error is the radial offset delta to 1 nm; positive outside the curve, negative inside. With a lag of
// 200 samples (0.57 mm) the same-instant command lies 16 um inside the circle, more than the 5 um offset tested
// here: the sign must come from the foot point, not from the same-instant tracking error.
TEST(Contour, CircleEqualsRadialOffsetWithinOneNanometre) {
  Circle ccw;
  ContourOptions planar;
  planar.plane_normal = Eigen::Vector3d::UnitZ();
  for (double delta : {0.02, -0.02, 0.005, -0.005, 0.001}) {
    for (double lag : {0.0, 13.6, 200.25}) {
      // CCW about +Z: n = Z x t points to the centre; outside (delta > 0): E points inward, n.E > 0.
      EXPECT_LT(circle_case(ccw, delta, lag, delta, planar), kNm) << "ccw planar delta " << delta << " lag " << lag;
      // Principal normal (no plane normal): also towards the centre.
      EXPECT_LT(circle_case(ccw, delta, lag, delta, {}), kNm) << "ccw principal delta " << delta << " lag " << lag;
    }
  }
  // Clockwise about +Z with the same plane normal: n = Z x t points outward, so the sign flips; the principal
  // normal still points to the centre, so it does not.
  Circle cw;
  cw.sense = -1.0;
  EXPECT_LT(circle_case(cw, 0.02, 31.5, -0.02, planar), kNm);
  EXPECT_LT(circle_case(cw, -0.02, 31.5, 0.02, planar), kNm);
  EXPECT_LT(circle_case(cw, 0.02, 31.5, 0.02, {}), kNm);
}

// A circle in a tilted plane (3D): principal normal, and the plane normal given as the tilted axis.
TEST(Contour, TiltedCircleIn3D) {
  Circle circ;
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 1, 1).normalized();
  circ.e1 = Eigen::Vector3d(1, -1, 0).normalized();
  circ.e2 = axis.cross(circ.e1);
  ContourOptions planar;
  planar.plane_normal = axis;
  for (double delta : {0.015, -0.015}) {
    EXPECT_LT(circle_case(circ, delta, 57.3, delta, {}), kNm);
    EXPECT_LT(circle_case(circ, delta, 57.3, delta, planar), kNm);
  }
}

namespace {

// Zigzag raster in XY: passes along +X, -X, +X, ... of `len` mm, stepover 0.25 mm in +Y through a straight
// connector. Records which command rows belong to which pass.
struct Raster {
  double len = 20.0, h = 0.01, stepover = 0.25;
  int passes = 8, conn = 25;  // connector samples (0.01 mm steps)
  std::vector<Eigen::Vector3d> pts;
  std::vector<int> pass_of;      // pass index of each row, -1 on connectors
  std::vector<int> first, last;  // rows of each pass
  Raster() {
    const int n = static_cast<int>(std::lround(len / h));
    for (int p = 0; p < passes; ++p) {
      const double y = p * stepover;
      first.push_back(static_cast<int>(pts.size()));
      for (int i = 0; i <= n; ++i) {
        const double x = (p % 2 == 0) ? i * h : len - i * h;
        pts.emplace_back(x, y, 1.0);
        pass_of.push_back(p);
      }
      last.push_back(static_cast<int>(pts.size()) - 1);
      if (p + 1 < passes)
        for (int j = 1; j < conn; ++j) {
          pts.emplace_back(pts.back().x(), y + stepover * j / conn, 1.0);
          pass_of.push_back(-1);
        }
    }
  }
  // Distance to pass p with its two connectors (the path the tool is on), analytic: three straight pieces.
  double own_distance(int p, const Eigen::Vector3d& a) const {
    const Eigen::Vector3d s = pts[first[p]], e = pts[last[p]];
    double d = seg_dist(a, s, e);
    if (p > 0) d = std::min(d, seg_dist(a, pts[last[p - 1]], s));
    if (p + 1 < passes) d = std::min(d, seg_dist(a, e, pts[first[p + 1]]));
    return d;
  }
};

}  // namespace

// The tool lags 1 mm (100 samples) along the path, four times the stepover, and sits 0.15 mm to one side, so that
// the neighbouring pass (0.10 mm away) is geometrically closer than its own (0.15 mm). While the tool is on a
// pass, the foot point must stay on that pass or its connectors, and the error must be the distance to them.
TEST(Contour, RasterNeverPicksTheNeighbouringPass) {
  const Raster r;
  const Eigen::MatrixXd cmd = rows(r.pts);
  const int lag = 100;
  for (double oy : {0.0, 0.15, -0.15}) {
    std::vector<Eigen::Vector3d> act;
    std::vector<int> src;
    for (int k = 0; k < static_cast<int>(r.pts.size()) + 200; ++k) {
      const int j = std::clamp(k - lag, 0, static_cast<int>(r.pts.size()) - 1);
      act.push_back(r.pts[j] + Eigen::Vector3d(0, oy, 0));
      src.push_back(j);
    }
    ContourOptions opt;
    opt.plane_normal = Eigen::Vector3d::UnitZ();
    const ContourError ce = contour_error(cmd, rows(act), opt);
    double max_e = 0.0;
    for (int k = 0; k < static_cast<int>(act.size()); ++k)
      max_e = std::max(max_e, (r.pts[std::min<int>(k, r.pts.size() - 1)] - act[k]).norm());
    EXPECT_GT(max_e, 4 * r.stepover) << "the lag must exceed the stepover for this test to mean anything";

    int checked = 0, neighbour_closer = 0;
    for (int k = 0; k < static_cast<int>(act.size()); ++k) {
      const int p = r.pass_of[src[k]];
      if (p < 0) continue;  // the tool is on a connector
      ++checked;
      // The foot's command row lies on pass p or on the connectors beside it.
      const int lo = p > 0 ? r.last[p - 1] : 0, hi = r.first[std::min(p + 1, r.passes - 1)];
      const int i = ce.foot_segment[k];
      ASSERT_TRUE(i >= lo && i < std::max(hi, r.last[p]))
          << "oy " << oy << " sample " << k << " on pass " << p << " has its foot on row " << i << " (pass "
          << r.pass_of[i] << ")";
      const double own = r.own_distance(p, act[k]);
      ASSERT_NEAR(std::abs(ce.signed_mm[k]), own, kNm) << "oy " << oy << " sample " << k;
      // Geometry check: somewhere the other pass really is closer (else the test proves nothing).
      for (int q : {p - 1, p + 1})
        if (q >= 0 && q < r.passes && seg_dist(act[k], r.pts[r.first[q]], r.pts[r.last[q]]) < own - 0.01)
          ++neighbour_closer;
      // Sign on the pass interior (0.2 mm from its ends, where the connectors are farther than the pass):
      // +X passes have n = +Y, -X passes n = -Y; E = -oy Y.
      if (oy != 0.0 && src[k] >= r.first[p] + 20 && src[k] <= r.last[p] - 20) {
        const double dir = (p % 2 == 0) ? 1.0 : -1.0;
        EXPECT_NEAR(ce.signed_mm[k], -oy * dir, kNm);
      }
    }
    EXPECT_GT(checked, 10000);
    if (oy != 0.0) {
      EXPECT_GT(neighbour_closer, 10000);
    }
  }
}

// Stationary stretches: rests before, between and after moves (repeated command rows), a 90-degree corner, and an
// actual offset out of the path's plane by 7 um: the distance is 7 um everywhere, never NaN, and the foot moves
// forward.
TEST(Contour, StationaryStretches) {
  std::vector<Eigen::Vector3d> v;
  const Eigen::Vector3d p0(1, 2, 3), p1(11, 2, 3), p2(11, 7, 3);
  for (int i = 0; i < 300; ++i) v.push_back(p0);
  for (int i = 1; i <= 500; ++i) v.push_back(p0 + (p1 - p0) * i / 500.0);
  for (int i = 0; i < 400; ++i) v.push_back(p1);
  for (int i = 1; i <= 500; ++i) v.push_back(p1 + (p2 - p1) * i / 500.0);
  for (int i = 0; i < 300; ++i) v.push_back(p2);
  const Eigen::MatrixXd cmd = rows(v);
  std::vector<Eigen::Vector3d> act;
  for (int k = 0; k < static_cast<int>(v.size()) + 100; ++k)
    act.push_back(v[std::clamp(k - 37, 0, static_cast<int>(v.size()) - 1)] + Eigen::Vector3d(0, 0, 0.007));
  for (const bool planar : {false, true}) {
    ContourOptions opt;
    if (planar) opt.plane_normal = Eigen::Vector3d::UnitZ();
    const ContourError ce = contour_error(cmd, rows(act), opt);
    ASSERT_TRUE(ce.signed_mm.allFinite());
    EXPECT_LT((ce.signed_mm - 0.007).abs().maxCoeff(), kNm);  // n lies in the plane: n.E = 0 counts as +
    for (Eigen::Index k = 1; k < ce.foot_segment.size(); ++k) EXPECT_GE(ce.foot_segment[k], ce.foot_segment[k - 1]);
  }

  // A command at rest (every row the same point), and a one-row command.
  Eigen::MatrixXd still(50, 3);
  still.rowwise() = Eigen::RowVector3d(4, 5, 6);
  Eigen::MatrixXd act2(80, 3);
  act2.rowwise() = Eigen::RowVector3d(4.003, 5.004, 6);
  for (const Eigen::MatrixXd& c : {still, Eigen::MatrixXd(still.topRows(1))}) {
    const ContourError ce = contour_error(c, act2);
    EXPECT_LT((ce.signed_mm - 0.005).abs().maxCoeff(), kNm);
    EXPECT_EQ(ce.foot_segment.maxCoeff(), 0);
  }
}

// Settling after the end: the actual overshoots the held last point and swings back and forth along the path,
// 1 um to the side. Beyond the end the distance is to the end point; before it, to the line.
TEST(Contour, SettlingAroundTheEndPoint) {
  const Line line;
  const Eigen::MatrixXd cmd = line.command();
  const Eigen::Vector3d end = line.at(line.n * line.h);
  std::vector<Eigen::Vector3d> act;
  std::vector<double> expected;
  for (Eigen::Index k = 0; k < cmd.rows(); ++k) {
    act.push_back(line.at(line.s_of(k - 10.0)) + 0.001 * line.normal);
    expected.push_back(-0.001);
  }
  for (int k = 0; k < 400; ++k) {
    const double along = 0.02 * std::exp(-k / 100.0) * std::sin(k / 15.0);  // +-20 um decaying swing
    act.push_back(end + along * line.dir + 0.001 * line.normal);
    // Beyond the end the foot is the end point itself; E points back and to the -n side.
    expected.push_back(along > 0 ? -std::hypot(along, 0.001) : -0.001);
  }
  ContourOptions opt;
  opt.plane_normal = Eigen::Vector3d::UnitZ();
  const ContourError ce = contour_error(cmd, rows(act), opt);
  for (std::size_t k = 0; k < act.size(); ++k) ASSERT_NEAR(ce.signed_mm[k], expected[k], kNm) << "sample " << k;
}

// MSE(CE) in um^2 on a known case: the actual alternates 2 um to one side and 4 um to the other.
// max |e| = 4 um, MSE = (4 + 16) / 2 = 10 um^2, RMS = sqrt(10) um.
TEST(Contour, MseInSquareMicrometres) {
  const Line line;
  const Eigen::MatrixXd cmd = line.command();
  std::vector<Eigen::Vector3d> act;
  for (Eigen::Index k = 0; k < cmd.rows() + 1; ++k)  // an even count (settling row included)
    act.push_back(line.at(line.s_of(k - 3.25)) + (k % 2 == 0 ? 0.002 : -0.004) * line.normal);
  ASSERT_EQ(act.size() % 2, 0u);
  ContourOptions opt;
  opt.plane_normal = Eigen::Vector3d::UnitZ();
  const ContourError ce = contour_error(cmd, rows(act), opt);
  EXPECT_NEAR(ce.max_abs_mm, 0.004, kNm);
  EXPECT_NEAR(ce.mse_um2, 10.0, 1e-6);
  EXPECT_NEAR(ce.rms_mm, std::sqrt(10.0) * 1e-3, 1e-9);
  EXPECT_NEAR(ce.signed_mm[0], -0.002, kNm);
  EXPECT_NEAR(ce.signed_mm[1], 0.004, kNm);
}

// A smooth 3D curve (a Lissajous-like knot) followed with a lag and random 0-10 um deviations: |error| equals a
// brute-force minimum over every command segment (a method of its own), to 1 nm.
TEST(Contour, MatchesBruteForceOnASmooth3DCurve) {
  const int n = 6000;
  std::vector<Eigen::Vector3d> v;
  for (int i = 0; i <= n; ++i) {
    const double t = 0.95 * 2 * kPi * i / n;  // open: a closed loop's end is as near its start as the start is
    v.emplace_back(30 * std::sin(t), 20 * std::sin(2 * t + 0.3), 5 * std::cos(3 * t));
  }
  const Eigen::MatrixXd cmd = rows(v);
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u(-0.01, 0.01);
  std::vector<Eigen::Vector3d> act;
  for (int k = 0; k <= n; ++k) {
    const int j = std::max(0, k - 40);
    act.push_back(v[j] + Eigen::Vector3d(u(rng), u(rng), u(rng)) / std::sqrt(3.0));
  }
  const ContourError ce = contour_error(cmd, rows(act));
  double worst = 0.0;
  for (int k = 0; k <= n; ++k) {
    double best = std::numeric_limits<double>::infinity();
    for (int i = 0; i < n; ++i) best = std::min(best, seg_dist(act[k], v[i], v[i + 1]));
    worst = std::max(worst, std::abs(std::abs(ce.signed_mm[k]) - best));
  }
  EXPECT_LT(worst, kNm);
}

// A path that folds back on itself: from S out 40 mm and back to S along the same line (a rapid that leaves and
// returns, as a program's first move from a job's start position does), then on at right angles for 20 mm. The
// actual follows 5 samples late; on the way back it passes exactly through the outgoing leg's samples, so the foot
// slides back down the outgoing leg (the same points: the distance is right). At S it must leave for the new leg:
// every distance stays within the lag (5 samples of at most 0.0515 mm), not the distance back to S (up to 20 mm).
TEST(Contour, FoldBackDoesNotTrapTheFootOnTheOutgoingLeg) {
  const Eigen::Vector3d s(2, 3, 4), o = s + Eigen::Vector3d(40, 0, 0), e = s + Eigen::Vector3d(0, 0, -20);
  std::vector<Eigen::Vector3d> v, act;
  for (int i = 0; i < 20; ++i) v.push_back(s);
  for (int i = 1; i <= 800; ++i) v.push_back(s + (o - s) * i / 800.0);
  for (int i = 0; i < 20; ++i) v.push_back(o);
  const int back0 = static_cast<int>(v.size());
  for (int i = 1; i <= 777; ++i) v.push_back(o + (s - o) * i / 777.0);  // not on the outgoing leg's samples
  const int back1 = static_cast<int>(v.size());
  for (int i = 1; i <= 400; ++i) v.push_back(s + (e - s) * i / 400.0);
  for (int i = 0; i < 20; ++i) v.push_back(e);
  for (int k = 0; k < static_cast<int>(v.size()); ++k) {
    const int j = std::max(0, k - 5);
    if (j >= back0 && j < back1) {  // on the way back: the outgoing sample nearest the command's point
      const double f = 1.0 - double(j - back0 + 1) / 777.0;
      act.push_back(s + (o - s) * std::round(f * 800.0) / 800.0);
    } else {
      act.push_back(v[j]);
    }
  }
  const ContourError ce = contour_error(rows(v), rows(act));
  EXPECT_LT(ce.max_abs_mm, 5 * 0.0515 + kNm);
}

TEST(Contour, WindowOptionAndDefault) {
  const Line line;
  const Eigen::MatrixXd cmd = line.command();
  Eigen::MatrixXd act = cmd;
  ContourOptions opt;
  opt.window_samples = 7;
  EXPECT_EQ(contour_error(cmd, act, opt).window_samples, 7);
  EXPECT_GE(contour_error(cmd, act).window_samples, 32);  // the lower bound of the default
}

TEST(Contour, RefusesBadInput) {
  Eigen::MatrixXd two(5, 2);
  two.setZero();
  Eigen::MatrixXd ok(5, 3);
  ok.setZero();
  EXPECT_THROW(contour_error(two, ok), Error);
  EXPECT_THROW(contour_error(ok, two), Error);
  EXPECT_THROW(contour_error(Eigen::MatrixXd(0, 3), ok), Error);
  Eigen::MatrixXd bad = ok;
  bad(3, 1) = std::numeric_limits<double>::quiet_NaN();
  try {
    contour_error(ok, bad);
    FAIL() << "NaN accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("row 3 column 1"), std::string::npos) << e.what();
  }
  ContourOptions opt;
  opt.plane_normal = Eigen::Vector3d::Zero();
  EXPECT_THROW(contour_error(ok, ok, opt), Error);
  // An empty actual gives an empty result.
  const ContourError ce = contour_error(ok, Eigen::MatrixXd(0, 3));
  EXPECT_EQ(ce.signed_mm.size(), 0);
}
