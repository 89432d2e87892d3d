// Every consumer of a programmed arc agrees with its frame (core/arc) on thousands of random arcs: each plane, both
// directions, extra turns, full circles (start == end), ends on the start's ray, helices, start and end radii that
// differ within the G-code reader's tolerance (LinuxCNC's: 0.0283 mm and 0.1 %). The consumers: the smooth path the
// interpolator follows (motion/smooth_path), the programmed track (sim::track_of), five-axis pose sampling
// (sim::program_pose_track), the kinematics' conversion to axis space (motion::toolpath_in_axis_space: arcs kept as
// arcs, or via points on the exact image, and the inverse-time feed from the arc's length) and the compensated
// program's G2/G3 pieces (methods/compensated_program, read back from its text).
// Where the consumers' output is points, the reference is geometric, not the frame's own evaluation: the angle about
// the centre, unwrapped point to point, must add up to the frame's signed sweep (direction, whole turns and full
// circles), and each point must sit on the arc at the fraction of the sweep its angle says.
#include "sim/pipeline.hpp"
#include "sim/tool_poses.hpp"

#include "core/arc.hpp"
#include "core/job.hpp"
#include "core/machine.hpp"
#include "methods/compensated_program.hpp"
#include "motion/kinematics.hpp"
#include "motion/smooth_path.hpp"
#include "removal/swept_tool.hpp"
#include "core/units.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <random>
#include <sstream>
#include <string>

namespace vmsim {
namespace {

using core::Vec6;
using Eigen::Vector3d;
using vmsim::core::units::kPi;

// Random arcs within the readers' tolerances (and within the xyzac-trt machine's travel).
class RandomArcs {
 public:
  explicit RandomArcs(unsigned seed) : rng_(seed) {}
  core::Move next(int k) {
    core::Move m;
    m.kind = core::MotionKind::Arc;
    m.plane = k % 3 == 0 ? core::ArcPlane::XY : k % 3 == 1 ? core::ArcPlane::ZX : core::ArcPlane::YZ;
    const core::PlaneAxes ax = core::plane_axes(m.plane);
    const int turns = u() < 0.7 ? 1 : 2 + static_cast<int>(3 * u());  // 1, or 2 to 4
    m.rotation = u() < 0.5 ? turns : -turns;
    const double r0 = 0.5 + 39.5 * u();
    double r1 = r0;
    if (u() < 0.5) r1 += (2 * u() - 1) * std::min(0.0283, 1e-3 * r0);
    const Eigen::Vector2d c(60 * u() - 30, 60 * u() - 30);
    const double a0 = 2 * kPi * u() - kPi;
    const double kind = u();
    double a1 = 2 * kPi * u() - kPi;
    if (kind < 0.15) a1 = a0;  // a full circle (equal radii) or an end on the start's ray (a spiral)
    m.centre_mm = c;
    m.start = m.end = Vec6::Zero();
    m.start[ax.axis1] = c[0] + r0 * std::cos(a0);
    m.start[ax.axis2] = c[1] + r0 * std::sin(a0);
    m.end[ax.axis1] = c[0] + r1 * std::cos(a1);
    m.end[ax.axis2] = c[1] + r1 * std::sin(a1);
    if (kind < 0.15 && r1 == r0) m.end = m.start;  // exactly: start == end
    m.start[ax.normal] = 20 * u() - 10;
    m.end[ax.normal] = u() < 0.5 ? m.start[ax.normal] : 20 * u() - 10;  // a helix half the time
    m.feed_mm_per_min = 600;
    m.source_line = k + 1;
    return m;
  }

 private:
  double u() { return dist_(rng_); }
  std::mt19937_64 rng_;
  std::uniform_real_distribution<double> dist_{0.0, 1.0};
};

core::ToolPath path_of(const core::Move& m) {
  core::ToolPath tp;
  tp.source_path = "random.ngc";
  tp.initial_position = m.start;
  tp.moves = {m};
  return tp;
}

// Points along an arc, checked against the frame geometrically: unwrapped angle steps (each below pi) adding up to the
// sweep, each point at the radius and normal coordinate of the fraction its angle gives. Returns the worst distance.
double worst_off_arc(const core::ArcFrame& f, const Eigen::MatrixXd& pts, double step_limit, std::string* why) {
  const Eigen::Index n = pts.rows();
  auto angle = [&](Eigen::Index k) {
    return std::atan2(pts(k, f.axis2) - f.centre_mm[1], pts(k, f.axis1) - f.centre_mm[0]);
  };
  double swept = 0, prev = angle(0), worst = 0;
  for (Eigen::Index k = 1; k < n; ++k) {
    const double a = angle(k), d = std::remainder(a - prev, 2 * kPi);
    if (std::abs(d) > step_limit) {
      *why = "a step of " + std::to_string(d) + " rad at point " + std::to_string(k);
      return 1e300;
    }
    swept += d;
    prev = a;
    const double t = k + 1 == n ? 1.0 : swept / f.sweep_rad;
    const Vec6 want = f.point_at(t);
    worst = std::max(worst, (pts.row(k).transpose() - want.head<3>()).norm());
  }
  const double miss = std::abs(swept - f.sweep_rad);
  if (miss > 1e-6) {
    *why = "swept " + std::to_string(swept) + " rad, the frame says " + std::to_string(f.sweep_rad);
    return 1e300;
  }
  return worst;
}

core::Machine xyzac() { return core::load_machine(std::string(VMSIM_SOURCE_DIR) + "/parts/machines/xyzac_trt.toml"); }

}  // namespace

TEST(ArcConsumers, SmoothPathPiecesAreTheFrame) {
  RandomArcs gen(1);
  for (int k = 0; k < 3000; ++k) {
    const core::Move m = gen.next(k);
    const core::ArcFrame f = core::arc_frame(m);
    const motion::SmoothPath sp = motion::build_smooth_path(path_of(m), motion::SmoothPathOptions{});
    int arcs = 0;
    for (const motion::PathPiece& pc : sp.pieces) {
      if (pc.kind != motion::PathPiece::Kind::Arc) continue;
      ++arcs;
      EXPECT_EQ(pc.arc_i1, f.axis1) << k;
      EXPECT_EQ(pc.arc_i2, f.axis2) << k;
      EXPECT_EQ(pc.theta0, f.start_angle_rad) << k;
      EXPECT_EQ(pc.dtheta, f.sweep_rad) << k;
      for (const double u : {0.0, 0.3, 0.7, 1.0})
        EXPECT_LT((pc.point_u(u) - motion::to_path_space(f.point_at(u))).norm(), 1e-9) << k << " u " << u;
    }
    EXPECT_EQ(arcs, 1) << k;
  }
}

TEST(ArcConsumers, ProgrammedTrackFollowsTheFrame) {
  RandomArcs gen(2);
  core::Job job;
  job.removal.track_tolerance_mm = 1e-3;
  for (int k = 0; k < 3000; ++k) {
    const core::Move m = gen.next(k);
    const core::ArcFrame f = core::arc_frame(m);
    sim::Motion mo;
    mo.program = path_of(m);
    const removal::PoseTrack tr = sim::track_of(mo, job, core::RemovalSpec::Motion::Program);
    ASSERT_GE(tr.tip_mm.rows(), 2) << k;
    EXPECT_EQ(tr.tip_mm.rows(), f.chords(1e-4) + 1) << k;
    EXPECT_EQ(Vector3d(tr.tip_mm.row(0).transpose()), m.start.head<3>()) << k;
    EXPECT_EQ(Vector3d(tr.tip_mm.bottomRows(1).transpose()), m.end.head<3>()) << k;
    std::string why;
    EXPECT_LT(worst_off_arc(f, tr.tip_mm, 0.5, &why), 1e-9) << k << ": " << why;
  }
}

TEST(ArcConsumers, FiveAxisPoseSamplingFollowsTheFrame) {
  const core::Machine mc = xyzac();
  const auto kin = motion::make_kinematics(mc);
  core::ToolSpec ts;
  ts.shape = core::ToolShape::Ball;
  ts.diameter_mm = 6;
  ts.corner_radius_mm = 3;
  const removal::Tool tool = removal::make_tool(ts);
  RandomArcs gen(3);
  for (int k = 0; k < 1000; ++k) {
    core::Move m = gen.next(k);
    m.tcp = true;  // tool-centre-point words with the table at zero: the tip is the programmed point
    const core::ArcFrame f = core::arc_frame(m);
    const core::ToolPath tp = path_of(m);
    const removal::PoseTrack tr =
        sim::program_pose_track(tp, motion::toolpath_in_axis_space(tp, mc), *kin, mc, tool, 1e-4);
    std::string why;
    EXPECT_LT(worst_off_arc(f, tr.tip_mm, 0.5, &why), 1e-9) << k << ": " << why;
  }
}

TEST(ArcConsumers, AxisSpaceConversionFollowsTheFrame) {
  const core::Machine mc = xyzac();
  const auto kin = motion::make_kinematics(mc);
  RandomArcs gen(4);
  for (int k = 0; k < 1000; ++k) {
    core::Move m = gen.next(k);
    m.tcp = true;
    const core::ArcFrame f = core::arc_frame(m);
    const int kind = (k / 3) % 3;  // k % 3 picks the plane
    if (kind == 0) {
      // The table still at zero: the arc stays the same arc in axis space.
      const core::ToolPath ax = motion::toolpath_in_axis_space(path_of(m), mc);
      const core::Move& am = ax.moves[0];
      ASSERT_EQ(am.kind, core::MotionKind::Arc) << k;
      const core::ArcFrame g = core::arc_frame(am);
      EXPECT_EQ(g.axis1, f.axis1) << k;
      EXPECT_NEAR(g.start_angle_rad, f.start_angle_rad, 1e-12) << k;
      EXPECT_NEAR(g.sweep_rad, f.sweep_rad, 1e-9) << k;
      continue;
    }
    // The table tilting (A) while the tip follows the arc, or tilted and still (the arc's plane is then no plane of
    // the axes): via points on the exact image, at their path parameter; a tilting table gives the move its
    // programmed duration from the arc's length (inverse-time feed, RS274/NGC).
    const bool tilting = kind == 1;
    const double a = (k % 2 ? 1 : -1) * (tilting ? 10 : 20) * kPi / 180;  // within A's travel
    m.end[core::kA] = a;
    if (!tilting) m.start[core::kA] = a;
    const core::ToolPath ax = motion::toolpath_in_axis_space(path_of(m), mc);
    const core::Move& am = ax.moves[0];
    if (!tilting && m.plane == core::ArcPlane::YZ) {
      // Tilted about X, an arc about X stays an arc about X, the same way round.
      ASSERT_EQ(am.kind, core::MotionKind::Arc) << k;
      EXPECT_NEAR(core::arc_frame(am).sweep_rad, f.sweep_rad, 1e-9) << k;
      continue;
    }
    ASSERT_EQ(am.kind, core::MotionKind::Line) << k;
    ASSERT_EQ(am.via.size(), am.via_s.size());
    // The via points in order, each on the arc where its parameter says, and the axis-space polyline's steps each
    // spanning less than half a turn of the arc (a chord that spans whole turns would cut them out).
    double s_prev = 0;
    for (std::size_t i = 0; i <= am.via.size(); ++i) {
      const double s = i < am.via.size() ? am.via_s[i] : 1.0;
      EXPECT_LT((s - s_prev) * std::abs(f.sweep_rad), kPi) << k << " via " << i;
      s_prev = s;
      if (i == am.via.size()) break;
      Eigen::VectorXd q(static_cast<Eigen::Index>(mc.axes.size()));
      for (std::size_t j = 0; j < mc.axes.size(); ++j)
        q[static_cast<Eigen::Index>(j)] = am.via[i][mc.axes[j].program_axis];
      const Vector3d tip = kin->forward(q, 0).tip_mm;
      EXPECT_LT((tip - f.point_at(am.via_s[i]).head<3>()).norm(), 1e-9) << k << " via " << i;
    }
    if (tilting) {
      ASSERT_EQ(am.feed_mode, core::FeedMode::InverseTime) << k;
      EXPECT_EQ(am.inverse_time_per_min, m.feed_mm_per_min / f.length_mm()) << k;
    }
  }
}

TEST(ArcConsumers, CompensatedProgramArcsAreTheFrame) {
  // A 3-axis machine; the compensation nil (compensated == original setpoints), so the written points are the arc's.
  core::Machine mc = core::load_machine(std::string(VMSIM_SOURCE_DIR) + "/parts/feedplan/chen2016_machine.toml");
  const auto kin = motion::make_kinematics(mc);
  RandomArcs gen(5);
  for (int k = 0; k < 3000; ++k) {
    const core::Move m = gen.next(k);
    const core::ArcFrame f = core::arc_frame(m);
    const core::ToolPath tp = path_of(m);
    const core::ToolPath ap = motion::toolpath_in_axis_space(tp, mc);
    const Eigen::Index ns = 200;
    core::Setpoints sp;
    for (const auto& a : mc.axes) sp.axis_names.push_back(a.name);
    sp.position.resize(ns, static_cast<Eigen::Index>(mc.axes.size()));
    sp.move_index = Eigen::ArrayXi::Zero(ns);
    Eigen::MatrixXd tip(ns, 3);
    for (Eigen::Index i = 0; i < ns; ++i) {
      const Vec6 p = f.point_at(double(i) / double(ns - 1));
      for (std::size_t a = 0; a < mc.axes.size(); ++a)
        sp.position(i, static_cast<Eigen::Index>(a)) = p[mc.axes[a].program_axis];
      tip.row(i) = p.head<3>().transpose();
    }
    methods::CompensatedProgramInput in;
    in.program = &tp;
    in.axis_path = &ap;
    in.setpoints = &sp;
    in.compensated = &sp.position;
    in.command_tip = &tip;
    in.machine = &mc;
    in.kinematics = kin.get();
    const methods::CompensatedProgram out = methods::write_compensated_program(in);
    // The arc's blocks ("G94 G17 G3 X.. Y.. Z.. I.. J.. F.."): with no correction, as many as pieces of the longest
    // angle for the radius (methods::arc_piece_max_angle_rad), the direction of the frame's sweep, each ending on the
    // arc, the centre words relative to the block's start.
    std::istringstream text(out.text);
    std::string line;
    int pieces = 0;
    const int n = f.chords(1.0, methods::arc_piece_max_angle_rad(std::max(f.start_radius_mm, f.end_radius_mm)));
    Vector3d last = m.start.head<3>();
    static constexpr char kCentreWord[3] = {'I', 'J', 'K'};
    while (std::getline(text, line)) {
      std::istringstream words(line);
      std::string w, dir;
      Vector3d p = Vector3d::Constant(NAN);
      Eigen::Vector2d centre = Eigen::Vector2d::Constant(NAN);
      while (words >> w) {
        if (w == "G2" || w == "G3") dir = w;
        if (w.size() < 2) continue;
        const double v = std::atof(w.c_str() + 1);
        if (w[0] == 'X' || w[0] == 'Y' || w[0] == 'Z') p[w[0] - 'X'] = v;
        if (w[0] == kCentreWord[f.axis1]) centre[0] = v;
        if (w[0] == kCentreWord[f.axis2]) centre[1] = v;
      }
      if (dir.empty()) continue;
      EXPECT_EQ(dir, f.sweep_rad > 0 ? "G3" : "G2") << k << ": " << line;
      ++pieces;
      // On the arc, but for the radial step that keeps every kink between pieces at least 5e-6 rad (the writer's
      // kMinKinkRad, see methods/compensated_program.cpp): at most twice that times the radius times the piece's angle.
      const double step = 2 * 5e-6 * std::max(f.start_radius_mm, f.end_radius_mm) * std::abs(f.sweep_rad) / n;
      EXPECT_LT((p - f.point_at(double(pieces) / n).head<3>()).norm(), 2e-6 + 1.01 * step) << k << ": " << line;
      EXPECT_NEAR(centre[0], f.centre_mm[0] - last[f.axis1], 2e-6) << k << ": " << line;
      EXPECT_NEAR(centre[1], f.centre_mm[1] - last[f.axis2], 2e-6) << k << ": " << line;
      last = p;
    }
    EXPECT_EQ(pieces, n) << k;
  }
}

}  // namespace vmsim
