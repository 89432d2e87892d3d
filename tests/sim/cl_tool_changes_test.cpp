// CL programs that change tools by TLDATA/ alone (issue 24 section 1), and five-axis programmed motion with tool
// changes. References, written elsewhere than the code under test:
// - the tools' own geometry (analytic): a flat end mill of diameter D plunged to depth h and moved straight leaves a
//   slot exactly D wide with a flat floor at -h;
// - single-tool runs of each stretch of the program: removal is a union of swept volumes, so a two-tool run must equal
//   the cell-by-cell minimum of the runs of each stretch alone (each alone cut and sampled with its own tool);
// - the error cases of issue 24 by the file, line and key their messages must name.
#include "core/error.hpp"
#include "core/job.hpp"
#include "sim/job_program.hpp"
#include "sim/run.hpp"
#include "sim/tools.hpp"
#include "tests/test_machines.hpp"

#include <gtest/gtest.h>

#include "tests/test_paths.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace vmsim::sim {
namespace {

namespace fs = std::filesystem;

fs::path cltc_write(const std::string& name, const std::string& text) {
  return vmsim::test::write_test_file("vmsim_cl_tool_changes_test", name, text);
}

using vmsim::test::kXyzTestMill;

// Tool 1 (TLDATA/ line 2, flat D6) cuts a slot along x at y = -5, 1 mm deep; tool 2 (TLDATA/ line 10, flat D4) one
// along y at x = 5, 2 mm deep. No LOAD/TOOL: the tools are numbered 1, 2 in order of appearance.
const char* kCltcProgram =
    "UNITS/MM\n"                                         // 1
    "TLDATA/MILL,6.0000,0.0000,20.0000,0.0000,0.0000\n"  // 2
    "FEDRAT/MMPM,600\n"                                  // 3
    "GOTO/-15,-5,5\n"                                    // 4: the start
    "GOTO/-15,-5,-1\n"                                   // 5
    "GOTO/15,-5,-1\n"                                    // 6
    "RAPID\n"                                            // 7
    "GOTO/15,-5,5\n"                                     // 8
    "$$ the second operation\n"                          // 9
    "TLDATA/MILL,4.0000,0.0000,20.0000,0.0000,0.0000\n"  // 10
    "RAPID\n"                                            // 11
    "GOTO/5,-15,5\n"                                     // 12
    "GOTO/5,-15,-2\n"                                    // 13
    "GOTO/5,15,-2\n"                                     // 14
    "RAPID\n"                                            // 15
    "GOTO/5,15,5\n"                                      // 16
    "FINI\n";

std::string cltc_job(const std::string& program, const std::string& tools, const std::string& motion) {
  return "[job]\nmachine = \"machine.toml\"\nprogram = \"" + program + "\"\n" + tools +
         "[stock]\ntype = \"box\"\nmin_mm = [-20.0, -20.0, -5.0]\nmax_mm = [20.0, 20.0, 0.0]\n"
         "[interpolation]\nperiod_ms = 1\ntolerance_mm = 0.005\n"
         "[removal]\nfield = \"zmap\"\nspacing_mm = 0.1\nmotion = \"" +
         motion + "\"\n[reference]\nkind = \"none\"\n";
}

double cltc_height(const core::HeightGrid& s, double x, double y) {
  const auto i = static_cast<Eigen::Index>(std::lround((x - s.x0_mm) / s.dx_mm));
  const auto j = static_cast<Eigen::Index>(std::lround((y - s.y0_mm) / s.dy_mm));
  return s.z_mm(j, i);
}

// Across a slot: the nodes below the stock top (its width), and the largest deviation of those strictly inside
// |c - centre| < width / 2 from the floor depth and of those outside from the stock top.
struct SlotProfile {
  int nodes = 0;
  double worst = 0;
};
SlotProfile cltc_slot(const core::HeightGrid& s, bool along_y, double at, double centre, double width, double depth) {
  SlotProfile p;
  const Eigen::Index n = along_y ? s.ny() : s.nx();
  for (Eigen::Index k = 0; k < n; ++k) {
    const double c = along_y ? s.y(k) : s.x(k);
    const double z = along_y ? cltc_height(s, at, c) : cltc_height(s, c, at);
    if (std::abs(c - centre) < width / 2 - 1e-6) p.worst = std::max(p.worst, std::abs(z + depth));
    if (std::abs(c - centre) > width / 2 + 1e-6) p.worst = std::max(p.worst, std::abs(z));
    p.nodes += z < -depth / 2 ? 1 : 0;
  }
  return p;
}

std::string cltc_error(const core::Job& job) {
  try {
    (void)run_job(job);
  } catch (const core::Error& e) {
    return e.what();
  }
  return "no error";
}

class ClToolChanges : public ::testing::TestWithParam<const char*> {};

// Each slot has its own TLDATA/ tool's width and depth: 6 mm wide and 1 mm deep, then 4 mm wide and 2 mm deep (the
// other tool's would be 2 mm off in width), on the programmed path and on the interpolator's setpoints.
TEST_P(ClToolChanges, EachSlotHasItsTldataToolsWidth) {
  cltc_write("machine.toml", kXyzTestMill);
  cltc_write("two.cl", kCltcProgram);
  core::Job job = core::load_job(cltc_write("two.toml", cltc_job("two.cl", "", GetParam())));
  const auto note = use_program_tool(job);
  ASSERT_TRUE(note);
  EXPECT_NE(note->find("order of first appearance"), std::string::npos) << *note;
  EXPECT_NE(note->find("T1: flat D6"), std::string::npos) << *note;
  EXPECT_NE(note->find("T2: flat D4"), std::string::npos) << *note;
  ASSERT_EQ(job.tools.size(), 2u);
  EXPECT_EQ(job.tools[0].number, 1);
  EXPECT_EQ(job.tools[1].number, 2);
  const RunResult r = run_job(job);
  ASSERT_TRUE(r.surface);
  const core::HeightGrid& s = *r.surface;
  // Slot 1 across y at x = -10 (tool 2 never reaches there), slot 2 across x at y = 10.
  const SlotProfile one = cltc_slot(s, true, -10.0, -5.0, 6.0, 1.0), two = cltc_slot(s, false, 10.0, 5.0, 4.0, 2.0);
  EXPECT_LT(one.worst, 1e-4) << "slot 1 is not a flat D6 slot 1 mm deep";
  EXPECT_LT(two.worst, 1e-4) << "slot 2 is not a flat D4 slot 2 mm deep";
  // Nodes every 0.1 mm across: 6 mm -> 59 or 61 (the two edge nodes lie on the tool's rim), 4 mm -> 39 or 41.
  EXPECT_NEAR(one.nodes * s.dy_mm, 6.0, 0.15);
  EXPECT_NEAR(two.nodes * s.dx_mm, 4.0, 0.15);
  EXPECT_NEAR(cltc_height(s, 5.0, -5.0), -2.0, 1e-4);  // the crossing: tool 2's floor under tool 1's
  // report.json: the tools are the program's, each with its moves and the TLDATA/ lines of its stretches.
  const nlohmann::json& tools = r.report.at("tools");
  EXPECT_EQ(tools.at("source").get<std::string>().rfind("program ", 0), 0u) << tools.dump();
  ASSERT_EQ(tools.at("list").size(), 2u);
  const nlohmann::json &t1 = tools["list"][0], &t2 = tools["list"][1];
  EXPECT_EQ(t1.at("tool"), "T1");
  EXPECT_EQ(t1.at("moves"), 3);  // lines 5, 6, 8
  EXPECT_EQ(t1.at("feed_moves"), 2);
  EXPECT_EQ(t1.at("program_lines"), nlohmann::json::array({2}));
  EXPECT_EQ(t2.at("tool"), "T2");
  EXPECT_EQ(t2.at("moves"), 4);  // lines 12, 13, 14, 16
  EXPECT_EQ(t2.at("feed_moves"), 2);
  EXPECT_EQ(t2.at("program_lines"), nlohmann::json::array({10}));
  EXPECT_GT(t1.at("sweeps").get<int>(), 0);
  EXPECT_GT(t2.at("sweeps").get<int>(), 0);
  std::printf("[ CL TOOLS ] %s: slot 1 %d nodes (6 mm), off %.1e mm; slot 2 %d nodes (4 mm), off %.1e mm\n", GetParam(),
              one.nodes, one.worst, two.nodes, two.worst);
}

INSTANTIATE_TEST_SUITE_P(Motions, ClToolChanges, ::testing::Values("program", "setpoints"));

// A job's one [tool] meeting a program that changes its geometry: an error naming the job, the program's tools with
// their TLDATA/ lines and all_tools; with all_tools the one tool cuts both slots (slot 2 then 6 mm wide).
TEST(ClToolChangesJob, OneToolNeedsAllTools) {
  cltc_write("machine.toml", kXyzTestMill);
  cltc_write("two.cl", kCltcProgram);
  const std::string one = "[tool]\ntype = \"flat\"\ndiameter_mm = 6.0\nflute_length_mm = 20.0\n";
  const std::string err = cltc_error(core::load_job(cltc_write("one.toml", cltc_job("two.cl", one, "program"))));
  for (const char* part : {"one.toml", "[tool] describes one tool", "of line 2", "of line 10", "all_tools = true"})
    EXPECT_NE(err.find(part), std::string::npos) << part << " not in: " << err;
  const RunResult r =
      run_job(core::load_job(cltc_write("all.toml", cltc_job("two.cl", one + "all_tools = true\n", "program"))));
  const SlotProfile two = cltc_slot(*r.surface, false, 10.0, 5.0, 6.0, 2.0);
  EXPECT_LT(two.worst, 1e-4);
}

// [[tools]] map the CL tools by their LOAD/TOOL numbers (7 and 3 here, the program's, not the order).
TEST(ClToolChangesJob, ToolsMapByLoadToolNumber) {
  cltc_write("machine.toml", kXyzTestMill);
  std::string prog = kCltcProgram;
  prog.insert(prog.find("FEDRAT"), "LOAD/TOOL,7\n");
  prog.insert(prog.find("RAPID\nGOTO/5,-15,5"), "LOAD/TOOL,3\n");
  cltc_write("loads.cl", prog);
  const std::string tools =
      "[[tools]]\nnumber = 3\ntype = \"flat\"\ndiameter_mm = 4.0\nflute_length_mm = 20.0\n"
      "[[tools]]\nnumber = 7\ntype = \"flat\"\ndiameter_mm = 6.0\nflute_length_mm = 20.0\n";
  core::Job job = core::load_job(cltc_write("loads.toml", cltc_job("loads.cl", tools, "program")));
  EXPECT_FALSE(use_program_tool(job));  // the job describes its tools
  const core::ToolPath tp = read_job_program(job);
  ASSERT_EQ(tp.program_tools.size(), 2u);
  EXPECT_EQ(tp.program_tools[0].number, 7);
  EXPECT_EQ(tp.program_tools[1].number, 3);
  const std::vector<int> per_move = move_tools(job, tp);
  for (std::size_t k = 0; k < tp.moves.size(); ++k)
    // With the two LOAD/TOOL records the second stretch's moves are lines 14 to 18: tool 3 ([[tools]] index 0).
    EXPECT_EQ(per_move[k], tp.moves[k].source_line > 12 ? 0 : 1) << "line " << tp.moves[k].source_line;
  const RunResult r = run_job(job);
  EXPECT_LT(cltc_slot(*r.surface, true, -10.0, -5.0, 6.0, 1.0).worst, 1e-4);
  EXPECT_LT(cltc_slot(*r.surface, false, 10.0, 5.0, 4.0, 2.0).worst, 1e-4);
}

// ---- five-axis programmed motion with tool changes ------------------------------------------------------------

// On the HAAS UMC-750-like B/C table: a ball D6 tilting from 0 to 20 degrees about y along a line in y, then (TLDATA/
// line 10) a bull-nose D8 R1 tilting from 10 to -10 degrees about x along a line in x; the stretches cut across each
// other. `part` 1: the first stretch alone; 2: the second alone, starting where the first left the tool; 0: both.
std::string cltc_five_axis(int part) {
  const double s20 = std::sin(20 * M_PI / 180), c20 = std::cos(20 * M_PI / 180);
  const double s10 = std::sin(10 * M_PI / 180), c10 = std::cos(10 * M_PI / 180);
  char first[512], second[512], start2[128];
  std::snprintf(first, sizeof first,
                "TLDATA/MILL,6.0000,3.0000,30.0000,0.0000,0.0000\n"  // 3 (UNITS/, FEDRAT/ before it)
                "GOTO/-5,-15,5,0,0,1\n"                              // 4: the start
                "GOTO/-5,-15,-1.5,0,0,1\n"                           // 5
                "GOTO/-5,15,-1.5,%.7f,0,%.7f\n"                      // 6
                "RAPID\nGOTO/-5,15,5\n",                             // 7, 8
                s20, c20);
  std::snprintf(second, sizeof second,
                "TLDATA/MILL,8.0000,1.0000,30.0000,0.0000,0.0000\n"  // 10 (after a comment line)
                "RAPID\nGOTO/-15,5,5,0,%.7f,%.7f\n"                  // 11, 12
                "GOTO/-15,5,-1,0,%.7f,%.7f\n"                        // 13
                "GOTO/15,5,-1,0,%.7f,%.7f\n"                         // 14
                "RAPID\nGOTO/15,5,5\n",                              // 15, 16
                -s10, c10, -s10, c10, s10, c10);
  std::snprintf(start2, sizeof start2, "GOTO/-5,15,5,%.7f,0,%.7f\n", s20, c20);
  const std::string head = "UNITS/MM\n";
  const std::string feed = "FEDRAT/MMPM,500\n";
  if (part == 1) return head + feed + first + "FINI\n";
  // Alone, the second stretch starts where the first left the tool (its last GOTO/'s point and axis).
  if (part == 2) return head + feed + start2 + second + "FINI\n";
  return head + feed + first + "$$ next operation\n" + second + "FINI\n";
}

std::string cltc_five_axis_job(const std::string& program) {
  return "[job]\nmachine = \"" + (fs::path(VMSIM_SOURCE_DIR) / "parts/machines/haas_umc750.toml").string() +
         "\"\nprogram = \"" + program +
         "\"\n[stock]\ntype = \"box\"\nmin_mm = [-20.0, -20.0, -5.0]\nmax_mm = [20.0, 20.0, 0.0]\n"
         "[interpolation]\nperiod_ms = 1\ntolerance_mm = 0.005\n"
         "[removal]\nfield = \"zmap\"\nspacing_mm = 0.25\nmotion = \"program\"\ntrack_tolerance_mm = 0.005\n"
         "[reference]\nkind = \"none\"\n";
}

TEST(ClToolChangesFiveAxis, EachStretchIsCutByItsToolOnTheProgrammedPath) {
  const fs::path both_file = cltc_write("both.cl", cltc_five_axis(0));
  cltc_write("first.cl", cltc_five_axis(1));
  cltc_write("second.cl", cltc_five_axis(2));
  core::Job both = core::load_job(cltc_write("both.toml", cltc_five_axis_job("both.cl")));
  core::Job first = core::load_job(cltc_write("first.toml", cltc_five_axis_job("first.cl")));
  core::Job second = core::load_job(cltc_write("second.toml", cltc_five_axis_job("second.cl")));
  for (core::Job* j : {&both, &first, &second}) ASSERT_TRUE(use_program_tool(*j));
  ASSERT_EQ(both.tools.size(), 2u);
  EXPECT_EQ(both.tools[0].shape, core::ToolShape::Ball);
  EXPECT_EQ(both.tools[1].shape, core::ToolShape::BullNose);
  const RunResult r = run_job(both), a = run_job(first), b = run_job(second);
  ASSERT_TRUE(r.surface && a.surface && b.surface);
  // The programmed track's poses carry their tool: two runs of sweeps, ball then bull-nose.
  ASSERT_EQ(r.cut.sweeps.runs.size(), 2u);
  EXPECT_EQ(r.cut.sweeps.runs[0].tool, 0);
  EXPECT_EQ(r.cut.sweeps.runs[1].tool, 1);
  EXPECT_EQ(r.cut.sweeps.runs[0].count, a.cut.sweeps.sweeps.size());
  EXPECT_EQ(r.cut.sweeps.runs[1].count, b.cut.sweeps.sweeps.size());
  const core::HeightArray &z = r.surface->z_mm, &za = a.surface->z_mm, &zb = b.surface->z_mm;
  ASSERT_EQ(z.rows(), za.rows());
  ASSERT_EQ(z.cols(), zb.cols());
  std::size_t differ = 0, cut_by_a = 0, cut_by_b = 0;
  double worst = 0;
  for (Eigen::Index j = 0; j < z.rows(); ++j)
    for (Eigen::Index i = 0; i < z.cols(); ++i) {
      const double u = std::min(za(j, i), zb(j, i));
      differ += z(j, i) != u ? 1 : 0;
      worst = std::max(worst, std::abs(double(z(j, i)) - u));
      cut_by_a += za(j, i) < zb(j, i) ? 1 : 0;
      cut_by_b += zb(j, i) < za(j, i) ? 1 : 0;
    }
  EXPECT_EQ(differ, 0u) << "largest difference " << worst << " mm";
  EXPECT_GT(cut_by_a, 200u);
  EXPECT_GT(cut_by_b, 200u);
  // The bull-nose's floor under its flat bottom at the middle of its line (axis vertical there, x = 0): z = -1.
  EXPECT_NEAR(cltc_height(*r.surface, 0.0, 5.0), -1.0, 5e-3);
  std::printf(
      "[ CL TOOLS ] five-axis program motion, two tools: %zu + %zu sweeps; %zu of %lld cells differ from the union of "
      "the stretches cut alone (largest %.2e mm)\n",
      r.cut.sweeps.runs[0].count, r.cut.sweeps.runs[1].count, differ, static_cast<long long>(z.size()), worst);
}

}  // namespace
}  // namespace vmsim::sim
