// The compensated program read back (methods/compensated_program, vmsim compensate's compensated.ngc and
// compensated_dense.ngc). A known correction field is given as the compensation's result: every setpoint moved by
// A tip (A a small matrix, sub-micrometre corrections), and the program written from it is read back by vmsim's
// G-code reader (program::read_program, which never sees the writer's numbers but through the text). Reference: the
// original program's points moved by the same field, as a user would expect the corrected program to hold them.
#include "core/arc.hpp"
#include "core/machine.hpp"
#include "methods/compensated_program.hpp"
#include "motion/interp.hpp"
#include "motion/kinematics.hpp"
#include "program/program.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

using namespace vmsim;
namespace fs = std::filesystem;

namespace {

fs::path temp_file(const std::string& name) {
  std::random_device rd;
  return fs::temp_directory_path() / ("vmsim_cprog_" + std::to_string(rd()) + "_" + name);
}

core::ToolPath read_text(const std::string& text, const std::string& name) {
  const fs::path p = temp_file(name);
  std::ofstream(p) << text;
  core::ToolPath tp = program::read_program(p);
  fs::remove(p);
  return tp;
}

struct Case {
  core::Machine machine;
  core::ToolPath program, axis_path;
  core::Setpoints sp;
  Eigen::MatrixXd tips, compensated;
  Eigen::Matrix3d a;
  std::unique_ptr<motion::Kinematics> kin;
  methods::CompensatedProgramInput input() const {
    methods::CompensatedProgramInput in;
    in.program = &program;
    in.axis_path = &axis_path;
    in.setpoints = &sp;
    in.compensated = &compensated;
    in.command_tip = &tips;
    in.machine = &machine;
    in.kinematics = kin.get();
    in.title = "test";
    return in;
  }
};

// A rapid approach, a line, a 60 degree arc (G3 about (30, 10)), a line, a rapid retract on the Mikron UCP 710;
// the correction field A tip (A within 2e-5: at most ~1.5 um here).
Case make_case() {
  Case c;
  c.machine = core::load_machine(std::string(VMSIM_SOURCE_DIR) + "/parts/machines/mikron_ucp710.toml");
  c.program = read_text(
      "G21 G90 G94 G17\nG0 X0 Y0 Z5\nG1 Z0 F2000\nG1 X30\nG3 X38.660254038 Y5 I0 J10\n"
      "G1 X50 Y20\nG0 Z5\nM30\n",
      "original.ngc");
  c.axis_path = motion::toolpath_in_axis_space(c.program, c.machine);
  c.sp = motion::interpolate(c.axis_path, c.machine, motion::InterpOptions{}).setpoints;
  c.kin = motion::make_kinematics(c.machine);
  c.a << 1.5e-5, -0.7e-5, 0.3e-5, 0.4e-5, 2.0e-5, -1.0e-5, 0.0, 0.5e-5, -1.2e-5;
  const Eigen::Index ns = c.sp.samples();
  c.tips.resize(ns, 3);
  c.compensated = c.sp.position;
  for (Eigen::Index k = 0; k < ns; ++k) {
    c.tips.row(k) = c.kin->forward(c.sp.position.row(k).transpose(), 0.0).tip_mm.transpose();
    const Eigen::Vector3d d = c.a * c.tips.row(k).transpose();
    for (int j = 0; j < 3; ++j) c.compensated(k, c.machine.axis_index(j)) += d[j];
  }
  return c;
}

}  // namespace

TEST(CompensatedProgram, ReadBackGivesTheCorrectedPointsAndTheOriginalMoves) {
  const Case c = make_case();
  const methods::CompensatedProgram cp = methods::write_compensated_program(c.input());
  EXPECT_EQ(cp.extension, "ngc");
  const core::ToolPath back = read_text(cp.text, "compensated.ngc");
  EXPECT_EQ(cp.blocks, static_cast<int>(back.moves.size()));
  double largest = 0;
  std::size_t j = 0;  // the read-back move
  for (std::size_t i = 0; i < c.program.moves.size(); ++i) {
    const core::Move& o = c.program.moves[i];
    SCOPED_TRACE(i);
    ASSERT_LT(j, back.moves.size()) << cp.text;
    // An arc is written in pieces about its programmed centre (methods::arc_pieces): the move ends with the last.
    double tolerance = 1.5e-6;
    if (o.kind == core::MotionKind::Arc) {
      while (j + 1 < back.moves.size() && back.moves[j + 1].kind == core::MotionKind::Arc) {
        EXPECT_NEAR(back.moves[j].centre_mm[0], o.centre_mm[0], 1e-6);
        EXPECT_NEAR(back.moves[j].centre_mm[1], o.centre_mm[1], 1e-6);
        ++j;
      }
      // The radial step that keeps the kinks between pieces at least 5e-6 rad (kMinKinkRad) may move the end.
      const core::ArcFrame f = core::arc_frame(o);
      tolerance += 2 * 5e-6 * f.start_radius_mm * methods::arc_piece_max_angle_rad(f.start_radius_mm);
    }
    const core::Move& b = back.moves[j++];
    EXPECT_EQ(b.kind, o.kind);
    EXPECT_EQ(b.rapid, o.rapid);
    if (!o.rapid) {
      EXPECT_EQ(b.feed_mm_per_min, o.feed_mm_per_min);
    }
    // The programmed point moved by the field there. The nearest setpoint to a vertex lies within the corner
    // tolerance (20 um) of it, where the field differs by |A| 0.02 mm < 1e-6 mm; the file holds 1e-6 mm.
    const Eigen::Vector3d want = o.end.head<3>() + c.a * o.end.head<3>();
    EXPECT_LT((b.end.head<3>() - want).norm(), tolerance) << b.end.head<3>().transpose() << " vs " << want.transpose();
    largest = std::max(largest, (c.a * o.end.head<3>()).norm());
    if (o.kind == core::MotionKind::Arc) {  // arcs stay arcs about their programmed centre
      EXPECT_NEAR(b.centre_mm[0], o.centre_mm[0], 1e-6);
      EXPECT_NEAR(b.centre_mm[1], o.centre_mm[1], 1e-6);
      EXPECT_EQ(b.rotation > 0, o.rotation > 0);
    }
  }
  EXPECT_EQ(j, back.moves.size());
  EXPECT_GT(largest, 5e-4);  // the field is not nil at the points: the check could fail
  EXPECT_NEAR(cp.largest_tip_correction_mm, largest, 1e-6);
}

TEST(CompensatedProgram, DenseFormReadBackIsTheCompensatedSetpoints) {
  const Case c = make_case();
  const Eigen::Index ns = c.sp.samples();
  const std::string text = methods::write_dense_program(c.compensated, Eigen::VectorXd::Zero(ns), c.machine, *c.kin,
                                                        c.sp.period_s, false, "test");
  const core::ToolPath back = read_text(text, "dense.ngc");
  // G0 to the first setpoint, then a G1 per setpoint; the reader drops the blocks that do not move (the setpoints at
  // rest), so each setpoint is either the next move's end or where the last one ended.
  std::size_t j = 0, dropped = 0;
  Eigen::Vector3d last = back.initial_position.head<3>();
  for (Eigen::Index k = 0; k < ns; ++k) {
    Eigen::Vector3d p;
    for (int a = 0; a < 3; ++a) p[a] = c.compensated(k, c.machine.axis_index(a));
    if (j < back.moves.size() && (back.moves[j].end.head<3>() - p).norm() < 1e-6) {
      if (j > 0) {
        EXPECT_EQ(back.moves[j].feed_mode, core::FeedMode::InverseTime);
        EXPECT_NEAR(back.moves[j].inverse_time_per_min, 60.0 / c.sp.period_s, 0.05);  // one block per Te
      }
      last = back.moves[j++].end.head<3>();
    } else {
      ASSERT_LT((p - last).norm(), 1e-6) << "setpoint " << k << " is neither the next block nor the last one";
      ++dropped;
    }
  }
  EXPECT_EQ(j, back.moves.size());
  EXPECT_LT(dropped, 10u);
}

// An arc whose correction varies along it (issue 23: with the correction only at the ends of quarter arcs, a circle cut
// 5.6 -> 26.7 um on the machine model). The correction field: radial d(theta) = 3 + 2 sin(2 theta) um outward and
// 1 um cos(theta) along the path, on every setpoint of a full circle (R 20) and a 135-degree arc after it. References:
// the field itself (each written piece, read back by vmsim's G-code reader and evaluated by core/arc, must stay within
// 0.1 um of the corrected circle R + d(theta), plus the 0.01 um the field changes between setpoints) and LinuxCNC's
// rule for a centre-format arc (interp_internal.hh: the radii to the start and to the end differ by at most
// 0.0283 mm and 0.1 %); each piece spans at most arc_piece_max_angle_rad about the programmed centre.
TEST(CompensatedProgram, ArcsFollowACorrectionThatVariesAlongThemWithinLinuxCncsRadiusRule) {
  Case c;
  c.machine = core::load_machine(std::string(VMSIM_SOURCE_DIR) + "/parts/machines/mikron_ucp710.toml");
  c.program = read_text(
      "G21 G90 G94 G17\nG0 X20 Y0 Z0\nG3 X20 Y0 I-20 J0 F3000\nG3 X-14.142135624 Y14.142135624 I-20 J0\nM30\n",
      "arcs.ngc");
  c.axis_path = motion::toolpath_in_axis_space(c.program, c.machine);
  c.sp = motion::interpolate(c.axis_path, c.machine, motion::InterpOptions{}).setpoints;
  c.kin = motion::make_kinematics(c.machine);
  const Eigen::Index ns = c.sp.samples();
  auto radial_um = [](double th) { return 3.0 + 2.0 * std::sin(2 * th); };
  c.tips.resize(ns, 3);
  c.compensated = c.sp.position;
  for (Eigen::Index k = 0; k < ns; ++k) {
    const Eigen::Vector3d p = c.kin->forward(c.sp.position.row(k).transpose(), 0.0).tip_mm;
    c.tips.row(k) = p.transpose();
    const double th = std::atan2(p.y(), p.x());
    const Eigen::Vector3d d = 1e-3 * (radial_um(th) * Eigen::Vector3d(std::cos(th), std::sin(th), 0) +
                                      std::cos(th) * Eigen::Vector3d(-std::sin(th), std::cos(th), 0));
    for (int j = 0; j < 3; ++j) c.compensated(k, c.machine.axis_index(j)) += d[j];
  }
  const methods::CompensatedProgram cp = methods::write_compensated_program(c.input());
  const core::ToolPath back = read_text(cp.text, "compensated.ngc");
  const double max_angle = methods::arc_piece_max_angle_rad(20.0);
  int arcs = 0;
  double worst_um = 0.0;
  for (const core::Move& b : back.moves) {
    if (b.kind != core::MotionKind::Arc) continue;
    ++arcs;
    SCOPED_TRACE(b.source_line);
    EXPECT_NEAR(b.centre_mm[0], 0.0, 1e-6);  // about the programmed centre
    EXPECT_NEAR(b.centre_mm[1], 0.0, 1e-6);
    const core::ArcFrame f = core::arc_frame(b);
    const double dr = std::abs(f.end_radius_mm - f.start_radius_mm);
    EXPECT_LE(dr, 2 * 0.01 * std::sqrt(2.0));
    EXPECT_LE(dr, 0.001 * std::max(f.start_radius_mm, f.end_radius_mm));
    EXPECT_LE(std::abs(f.sweep_rad), max_angle * (1 + 1e-6));
    EXPECT_GT(f.sweep_rad, 0.0);  // G3 stays G3
    for (int i = 0; i <= 20; ++i) {
      const core::Vec6 p = f.point_at(i / 20.0);
      const double th = std::atan2(p[1], p[0]);
      worst_um = std::max(worst_um, std::abs(std::hypot(p[0], p[1]) - 20.0 - 1e-3 * radial_um(th)) * 1e3);
    }
  }
  std::printf("%d arc pieces (at most %.2f deg each), largest distance from the corrected circle %.4f um\n", arcs,
              max_angle * 180 / std::acos(-1.0), worst_um);
  EXPECT_GE(arcs, static_cast<int>(std::ceil((2 + 0.75) * std::acos(-1.0) / max_angle)));
  EXPECT_LT(worst_um, 0.11);
}
