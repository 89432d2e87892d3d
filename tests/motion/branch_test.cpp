// The inverse's solution branch on a B/C trunnion table (parts/machines/haas_umc750.toml: B -35 .. +120 deg, C
// continuous): a tool axis tilted by t in azimuth phi has the two solutions (B, C) = (t, phi) and (-t, phi + 180 deg)
// (the tool axis is (sin B cos C, sin B sin C, cos B), the machine file's header), so beyond a 35 deg tilt only the
// positive branch is within travel. References: that closed form, the machine's travels, and the forward transform
// (the axes chosen must give back the programmed tip and tool axis). The real NX files (../shared/data/real, skipped
// when absent) must go through on the machine they were made for.
#include "core/error.hpp"
#include "core/machine.hpp"
#include "core/units.hpp"
#include "motion/kinematics.hpp"
#include "program/apt.hpp"
#include "program/program.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

namespace vmsim::motion {
namespace {

namespace fs = std::filesystem;
using vmsim::core::units::kDegToRad;

core::Machine haas() {
  return core::load_machine(fs::path(VMSIM_SOURCE_DIR) / "parts" / "machines" / "haas_umc750.toml");
}

// A GOTO/ with the tool axis tilted by tilt_deg from +Z towards azimuth az_deg.
std::string go(double x, double y, double z, double tilt_deg, double az_deg) {
  char b[200];
  std::snprintf(b, sizeof b, "GOTO/%.6f,%.6f,%.6f,%.9f,%.9f,%.9f\n", x, y, z,
                std::sin(tilt_deg * kDegToRad) * std::cos(az_deg * kDegToRad),
                std::sin(tilt_deg * kDegToRad) * std::sin(az_deg * kDegToRad), std::cos(tilt_deg * kDegToRad));
  return b;
}

Eigen::VectorXd axes_of(const core::Vec6& v, const core::Machine& m) {
  Eigen::VectorXd q(static_cast<Eigen::Index>(m.axes.size()));
  for (std::size_t i = 0; i < m.axes.size(); ++i) q[static_cast<Eigen::Index>(i)] = v[m.axes[i].program_axis];
  return q;
}

// Every axis-space move within the travels and giving back the programmed pose at its end (tip 1e-6 mm, axis 1e-9).
void expect_follows(const core::ToolPath& prog, const core::ToolPath& axes, const core::Machine& machine) {
  const auto kin = make_kinematics(machine);
  ASSERT_EQ(prog.moves.size(), axes.moves.size());
  double tip = 0, ax = 0;
  for (std::size_t k = 0; k < axes.moves.size(); ++k) {
    const core::Move& am = axes.moves[k];
    for (const core::Vec6* v : {&am.start, &am.end}) {
      const Eigen::VectorXd q = axes_of(*v, machine);
      for (std::size_t i = 0; i < machine.axes.size(); ++i) {
        const core::MachineAxis& a = machine.axes[i];
        if (a.continuous) continue;
        EXPECT_GE(q[static_cast<Eigen::Index>(i)], a.travel_min - 1e-9) << a.name << " move " << k;
        EXPECT_LE(q[static_cast<Eigen::Index>(i)], a.travel_max + 1e-9) << a.name << " move " << k;
      }
    }
    const ToolPose p = kin->forward(axes_of(am.end, machine), am.tool_length_offset_mm);
    tip = std::max(tip, (p.tip_mm - prog.moves[k].end.head<3>()).norm());
    ax = std::max(ax, (p.axis - prog.moves[k].tool_axis_end->normalized()).norm());
  }
  EXPECT_LT(tip, 1e-6);
  EXPECT_LT(ax, 1e-9);
}

// Start tilted 20 deg towards -X: the least rotary motion from B = C = 0 is the negative branch (B -20, C 0). A rapid
// then re-orients to 50 deg towards -X, which the negative branch cannot reach (B -50 < -35): the rapid takes the
// other branch (B 50, C 180). Before, this stopped with "the rotary axes would have to jump".
TEST(BranchChoice, RapidSwitchesToTheBranchWithinTravel) {
  const core::Machine m = haas();
  const std::string text = "UNITS/MM\nFEDRAT/MMPM,500\n" + go(0, 0, 50, 20, 180) + go(10, 0, 50, 20, 180) + "RAPID\n" +
                           go(10, 0, 80, 50, 180) +  // 5-6
                           go(20, 0, 80, 50, 180) + go(30, 5, 75, 60, 170);
  const core::ToolPath prog = program::read_apt_text(text, "branch.cls");
  const core::ToolPath axes = toolpath_in_axis_space(prog, m);
  expect_follows(prog, axes, m);
  const int ib = 4, ic = 5;  // program axes B and C
  EXPECT_NEAR(axes.moves[0].end[ib], -20 * kDegToRad, 1e-9);
  EXPECT_NEAR(std::remainder(axes.moves[0].end[ic], 2 * core::units::kPi), 0.0, 1e-9);
  ASSERT_TRUE(axes.moves[1].rapid);
  EXPECT_NEAR(axes.moves[1].end[ib], 50 * kDegToRad, 1e-9);
  EXPECT_NEAR(std::abs(std::remainder(axes.moves[1].end[ic], 2 * core::units::kPi)), 180 * kDegToRad, 1e-9);
  EXPECT_TRUE(axes.moves[1].via.empty()) << "the switching rapid runs straight in axis space";
  EXPECT_NEAR(axes.moves[3].end[ib], 60 * kDegToRad, 1e-9);
}

// The same switch at a feed move is not allowed mid-path, but the path's start is a switch point: the whole first
// stretch is taken on the positive branch when the negative one runs out of travel.
TEST(BranchChoice, FirstStretchStartsOnTheBranchThatFits) {
  const core::Machine m = haas();
  const std::string text =
      "UNITS/MM\nFEDRAT/MMPM,500\n" + go(0, 0, 50, 20, 180) + go(10, 0, 50, 40, 180) + go(20, 0, 50, 60, 180);
  const core::ToolPath prog = program::read_apt_text(text, "branch.cls");
  const core::ToolPath axes = toolpath_in_axis_space(prog, m);
  expect_follows(prog, axes, m);
  EXPECT_NEAR(axes.initial_position[4], 20 * kDegToRad, 1e-9);
  EXPECT_NEAR(axes.moves.back().end[4], 60 * kDegToRad, 1e-9);
}

// No branch fits: a tilt of 125 deg is beyond +120 on one branch and -35 on the other. The error names the line and
// the limit; at a rapid it names both branches' reasons.
TEST(BranchChoice, NoBranchFitsNamesLineAndLimit) {
  const core::Machine m = haas();
  {
    const std::string text = "UNITS/MM\nFEDRAT/MMPM,500\n" + go(0, 0, 50, 10, 0) + go(10, 0, 50, 125, 0);
    const core::ToolPath prog = program::read_apt_text(text, "branch.cls");
    try {
      (void)toolpath_in_axis_space(prog, m);
      ADD_FAILURE() << "no error";
    } catch (const core::Error& e) {
      const std::string w = e.what();
      EXPECT_NE(w.find("branch.cls:4:"), std::string::npos) << w;
      EXPECT_NE(w.find("[-35.0000, 120.0000]"), std::string::npos) << w;
    }
  }
  {
    // The path starts on the rapid of line 5 (a switch point). On the branch nearest B = C = 0 (B -20) the feed move
    // of line 6 to 50 deg meets B = -35; on the other, line 7 needs 125 deg.
    const std::string text = "UNITS/MM\nFEDRAT/MMPM,500\n" + go(0, 0, 50, 20, 180) + "RAPID\n" + go(0, 0, 60, 20, 180) +
                             go(10, 0, 60, 50, 180) + go(20, 0, 60, 125, 180);
    const core::ToolPath prog = program::read_apt_text(text, "branch.cls");
    try {
      (void)toolpath_in_axis_space(prog, m);
      ADD_FAILURE() << "no error";
    } catch (const core::Error& e) {
      const std::string w = e.what();
      EXPECT_NE(w.find("branch.cls:5:"), std::string::npos) << w;
      EXPECT_NE(w.find("no solution branch"), std::string::npos) << w;
      EXPECT_NE(w.find("branch.cls:6:"), std::string::npos) << w;  // the jump on the present branch
      EXPECT_NE(w.find("-35.0000"), std::string::npos) << w;
      EXPECT_NE(w.find("branch.cls:7:"), std::string::npos) << w;  // the unreachable tilt on the other
    }
  }
}

// The three NX files through the machine they were made for: within travel, the programmed poses given back.
TEST(BranchChoice, NxFilesRunOnTheHaas) {
  const fs::path dir = fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "cam" / "nx_clsf_haas_umc750";
  if (!fs::exists(dir)) GTEST_SKIP() << dir << " is absent (the real CAM programs of ../shared)";
  const core::Machine m = haas();
  for (const char* name : {"APT_Project2.txt", "APT_Variable_Axis.txt", "APT_code.txt"}) {
    SCOPED_TRACE(name);
    program::ProgramOptions o;
    o.program_units = program::LengthUnit::Inch;
    const core::ToolPath prog = program::read_program(dir / name, o);
    const core::ToolPath axes = toolpath_in_axis_space(prog, m);
    expect_follows(prog, axes, m);
    int switches = 0;
    for (std::size_t k = 0; k < axes.moves.size(); ++k)
      if (axes.moves[k].rapid && k > 0 && std::abs(axes.moves[k].end[4] - axes.moves[k].start[4]) > 1e-6 &&
          std::signbit(axes.moves[k].end[4]) != std::signbit(axes.moves[k].start[4]))
        ++switches;
    std::printf("[ HAAS     ] %s: %zu moves through the B/C table, %d rapids change the sign of B\n", name,
                axes.moves.size(), switches);
  }
}

}  // namespace
}  // namespace vmsim::motion
