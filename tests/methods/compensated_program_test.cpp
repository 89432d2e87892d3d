// The compensated program read back (methods/compensated_program, vmsim compensate's compensated.ngc and
// compensated_dense.ngc). A known correction field is given as the compensation's result: every setpoint moved by
// A tip (A a small matrix, sub-micrometre corrections), and the program written from it is read back by vmsim's
// G-code reader (program::read_program, which never sees the writer's numbers but through the text). Reference: the
// original program's points moved by the same field, as a user would expect the corrected program to hold them.
#include "core/machine.hpp"
#include "methods/compensated_program.hpp"
#include "motion/interp.hpp"
#include "motion/kinematics.hpp"
#include "program/program.hpp"

#include <gtest/gtest.h>

#include <cmath>
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
  ASSERT_EQ(back.moves.size(), c.program.moves.size()) << cp.text;
  EXPECT_EQ(cp.blocks, static_cast<int>(c.program.moves.size()));
  double largest = 0;
  for (std::size_t i = 0; i < c.program.moves.size(); ++i) {
    const core::Move &o = c.program.moves[i], &b = back.moves[i];
    SCOPED_TRACE(i);
    EXPECT_EQ(b.kind, o.kind);
    EXPECT_EQ(b.rapid, o.rapid);
    if (!o.rapid) {
      EXPECT_EQ(b.feed_mm_per_min, o.feed_mm_per_min);
    }
    // The programmed point moved by the field there. The nearest setpoint to a vertex lies within the corner
    // tolerance (20 um) of it, where the field differs by |A| 0.02 mm < 1e-6 mm; the file holds 1e-6 mm.
    const Eigen::Vector3d want = o.end.head<3>() + c.a * o.end.head<3>();
    EXPECT_LT((b.end.head<3>() - want).norm(), 1.5e-6) << b.end.head<3>().transpose() << " vs " << want.transpose();
    largest = std::max(largest, (c.a * o.end.head<3>()).norm());
    if (o.kind == core::MotionKind::Arc) {  // arcs stay arcs about their programmed centre
      EXPECT_NEAR(b.centre_mm[0], o.centre_mm[0], 1e-6);
      EXPECT_NEAR(b.centre_mm[1], o.centre_mm[1], 1e-6);
      EXPECT_EQ(b.rotation > 0, o.rotation > 0);
    }
  }
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
