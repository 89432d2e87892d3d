// Which tool last cut where (issue 24 section 1, tools.png): the map Cut::tool_map and report.json's
// last_cut_area_mm2. References, written elsewhere than the code under test:
// - the tools' geometry (analytic): a flat end mill of radius R moved straight at a constant depth cuts exactly the
//   points within R of its path (a stadium); where a later, deeper slot crosses an earlier one, the later tool lowers
//   the floor again and is the last to cut there;
// - the map's own node count times the grid's cell area, and the stadiums' analytic areas (within the band of nodes
//   a perimeter can move by half a cell).
#include "core/job.hpp"
#include "sim/job_program.hpp"
#include "sim/run.hpp"
#include "sim/tools.hpp"
#include "tests/test_machines.hpp"

#include <gtest/gtest.h>

#include "tests/test_paths.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

namespace vmsim::sim {
namespace {

namespace fs = std::filesystem;

fs::path tmap_write(const std::string& name, const std::string& text) {
  return vmsim::test::write_test_file("vmsim_tool_map_test", name, text);
}

using vmsim::test::kXyzTestMill;

// The two-slot program of cl_tool_changes_test.cpp: tool 1 (flat D6) a slot along x at y = -5 from x = -15 to 15,
// 1 mm deep; tool 2 (flat D4) one along y at x = 5 from y = -15 to 15, 2 mm deep (crossing slot 1).
const char* kTmapProgram =
    "UNITS/MM\n"
    "TLDATA/MILL,6.0000,0.0000,20.0000,0.0000,0.0000\n"
    "FEDRAT/MMPM,600\n"
    "GOTO/-15,-5,5\n"
    "GOTO/-15,-5,-1\n"
    "GOTO/15,-5,-1\n"
    "RAPID\n"
    "GOTO/15,-5,5\n"
    "TLDATA/MILL,4.0000,0.0000,20.0000,0.0000,0.0000\n"
    "RAPID\n"
    "GOTO/5,-15,5\n"
    "GOTO/5,-15,-2\n"
    "GOTO/5,15,-2\n"
    "RAPID\n"
    "GOTO/5,15,5\n"
    "FINI\n";

std::string tmap_job(const std::string& tools, const std::string& motion) {
  return "[job]\nmachine = \"machine.toml\"\nprogram = \"two.cl\"\n" + tools +
         "[stock]\ntype = \"box\"\nmin_mm = [-20.0, -20.0, -5.0]\nmax_mm = [20.0, 20.0, 0.0]\n"
         "[interpolation]\nperiod_ms = 1\ntolerance_mm = 0.005\n"
         "[removal]\nfield = \"zmap\"\nspacing_mm = 0.1\nmotion = \"" +
         motion + "\"\n[reference]\nkind = \"none\"\n";
}

// Distance from (x, y) to the segment a-b.
double tmap_segment_distance(double x, double y, double ax, double ay, double bx, double by) {
  const double dx = bx - ax, dy = by - ay;
  const double t = std::clamp(((x - ax) * dx + (y - ay) * dy) / (dx * dx + dy * dy), 0.0, 1.0);
  return std::hypot(x - ax - t * dx, y - ay - t * dy);
}

class ToolMapSlots : public ::testing::TestWithParam<const char*> {};

// Tool 1 exactly on slot 1's nodes outside slot 2, tool 2 exactly on slot 2's, uncut elsewhere (nodes within 10 um of
// a slot's edge are left out: twice the interpolation tolerance, by which the setpoints may round the plunges'
// corners; on the edge itself round-off decides); areas = nodes x cell area.
TEST_P(ToolMapSlots, EachNodeIsCreditedToTheToolThatCutItLast) {
  tmap_write("machine.toml", kXyzTestMill);
  tmap_write("two.cl", kTmapProgram);
  core::Job job = core::load_job(tmap_write("two.toml", tmap_job("", GetParam())));
  ASSERT_TRUE(use_program_tool(job));
  ASSERT_EQ(job_tools(job).size(), 2u);
  const RunResult r = run_job(job);
  ASSERT_TRUE(r.surface);
  ASSERT_TRUE(r.cut.tool_map) << "a two-tool job makes a tool map";
  const ToolMap& m = *r.cut.tool_map;
  const core::HeightGrid& s = *r.surface;
  ASSERT_EQ(m.nu, s.nx());
  ASSERT_EQ(m.nv, s.ny());
  int wrong = 0, edge = 0;
  std::size_t count[3] = {0, 0, 0};  // tool 1, tool 2, uncut: every node, the edges included
  for (int j = 0; j < m.nv; ++j)
    for (int i = 0; i < m.nu; ++i) {
      const std::uint8_t t = m.at(i, j);
      ++count[t == ToolMap::kUncut ? 2 : t];
      const double x = s.x(i), y = s.y(j);
      const double d1 = tmap_segment_distance(x, y, -15, -5, 15, -5) - 3.0;
      const double d2 = tmap_segment_distance(x, y, 5, -15, 5, 15) - 2.0;
      if (std::abs(d1) < 0.01 || std::abs(d2) < 0.01) {
        ++edge;
        continue;
      }
      const std::uint8_t expected = d2 < 0 ? 1 : d1 < 0 ? 0 : ToolMap::kUncut;
      if (t != expected && ++wrong <= 5)
        ADD_FAILURE() << "node x " << x << " y " << y << ": tool " << int(t) << ", expected " << int(expected);
    }
  EXPECT_EQ(wrong, 0) << "nodes credited to the wrong tool (of " << m.nu * m.nv << ", " << edge << " on edges)";
  const nlohmann::json& list = r.report["tools"]["list"];
  ASSERT_EQ(list.size(), 2u);
  const double cell = s.dx_mm * s.dy_mm;
  EXPECT_DOUBLE_EQ(list[0]["last_cut_area_mm2"].get<double>(), static_cast<double>(count[0]) * cell);
  EXPECT_DOUBLE_EQ(list[1]["last_cut_area_mm2"].get<double>(), static_cast<double>(count[1]) * cell);
  // Analytic: slot 2 a stadium 4 x 30 mm with round ends (all inside the stock); slot 1 a stadium 6 x 30 mm less the
  // 4 x 6 mm rectangle slot 2 takes from it. Node counts differ from the areas by at most a cell-wide band around the
  // perimeters (about 70 and 90 mm long).
  const double pi = std::acos(-1.0);
  const double a2 = 4.0 * 30.0 + pi * 4.0, a1 = 6.0 * 30.0 + pi * 9.0 - 24.0;
  EXPECT_NEAR(list[1]["last_cut_area_mm2"].get<double>(), a2, 0.5 * 0.1 * 72.6);
  EXPECT_NEAR(list[0]["last_cut_area_mm2"].get<double>(), a1, 0.5 * 0.1 * 90.0);
  std::printf(
      "[ TOOL MAP ] %s: tool 1 %zu nodes (%.2f mm^2, analytic %.2f), tool 2 %zu nodes (%.2f mm^2, analytic "
      "%.2f), uncut %zu, %d edge nodes\n",
      GetParam(), count[0], count[0] * cell, a1, count[1], count[1] * cell, a2, count[2], edge);
}

INSTANTIATE_TEST_SUITE_P(Motions, ToolMapSlots, ::testing::Values("program", "setpoints"));

// One tool: no map and no last_cut_area_mm2 (the single-tool run and its report stay as they were).
TEST(ToolMapSingleTool, MakesNoMap) {
  tmap_write("machine.toml", kXyzTestMill);
  tmap_write("two.cl", kTmapProgram);
  const std::string one = "[tool]\ntype = \"flat\"\ndiameter_mm = 6.0\nflute_length_mm = 20.0\nall_tools = true\n";
  const RunResult r = run_job(core::load_job(tmap_write("one.toml", tmap_job(one, "program"))));
  EXPECT_FALSE(r.cut.tool_map);
  ASSERT_EQ(r.report["tools"]["list"].size(), 1u);
  EXPECT_FALSE(r.report["tools"]["list"][0].contains("last_cut_area_mm2"));
}

}  // namespace
}  // namespace vmsim::sim
