// CL programs that change tools by TLDATA/ (and CUTTER/, LOAD/TOOL) through the APT reader (issue 24 section 1).
// References, from outside the reader: the programs' own text (which TLDATA/ and LOAD/TOOL records stand before each
// move's line, found here by a plain line scan), and the numbering rules of issue 24 (the program's LOAD/TOOL numbers
// when it has them, else the order of first appearance). The real file is NX's APT_Project2.txt of the MECH491
// post-processor course project (CC0), read from ../shared/data/real (skipped when absent).
#include "core/units.hpp"
#include "program/apt.hpp"
#include "program/program.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

namespace vmsim::program {
namespace {

namespace fs = std::filesystem;

core::ToolPath atc_read(const std::string& text) { return read_apt_text("UNITS/MM\n" + text, "tc.cls"); }

std::vector<int> atc_numbers(const core::ToolPath& tp) {
  std::vector<int> n;
  for (const core::Move& m : tp.moves) n.push_back(m.tool_number);
  return n;
}

TEST(AptToolChanges, TldataAloneNumbersToolsInOrderOfAppearance) {
  const core::ToolPath tp = atc_read(
      "TLDATA/MILL,10,5,50,0,0\nFEDRAT/MMPM,100\nGOTO/0,0,0\nGOTO/1,0,0\n"  // 2-5
      "TLDATA/MILL,10,5,50,0,0\n"                                           // 6: the same tool
      "GOTO/2,0,0\n"                                                        // 7
      "TLDATA/MILL,6,0,30,0,0\n"                                            // 8: another
      "GOTO/3,0,0\n"                                                        // 9
      "CUTTER/10,5\n"                                                       // 10: the first again (no length)
      "GOTO/4,0,0\n");                                                      // 11
  EXPECT_EQ(atc_numbers(tp), (std::vector<int>{1, 1, 2, 1}));
  ASSERT_EQ(tp.program_tools.size(), 2u);
  const core::ProgramTool &a = tp.program_tools[0], &b = tp.program_tools[1];
  EXPECT_EQ(a.number, 1);
  EXPECT_EQ(a.diameter_mm, 10.0);
  EXPECT_EQ(a.corner_radius_mm, 5.0);
  EXPECT_EQ(a.length_mm, 50.0);
  EXPECT_EQ(a.line, 2);
  EXPECT_EQ(a.stretch_lines, (std::vector<int>{2, 10}));  // the records in force at each stretch's first move
  EXPECT_FALSE(a.numbered_by_program);
  EXPECT_EQ(b.number, 2);
  EXPECT_EQ(b.diameter_mm, 6.0);
  EXPECT_EQ(b.line, 8);
  EXPECT_EQ(b.stretch_lines, (std::vector<int>{8}));
  EXPECT_TRUE(tp.warnings.empty()) << tp.warnings.front();
  EXPECT_EQ(tp.tool_diameter_mm, 10.0);  // the program's first tool, as before
  EXPECT_EQ(tp.tool_line, 2);
}

TEST(AptToolChanges, OneGeometryWithoutLoadToolStaysToolZero) {
  const core::ToolPath tp = atc_read(
      "TLDATA/MILL,10,5,50,0,0\nFEDRAT/MMPM,100\nGOTO/0,0,0\nGOTO/1,0,0\nTLDATA/MILL,10,5,50,0,0\nGOTO/2,0,0\n");
  EXPECT_EQ(atc_numbers(tp), (std::vector<int>{0, 0}));
  ASSERT_EQ(tp.program_tools.size(), 1u);
  EXPECT_EQ(tp.program_tools[0].number, 0);
}

// NX writes TLDATA/ before its operation's LOAD/TOOL: the number is the one in force at the move.
TEST(AptToolChanges, LoadToolNumbersAreTheProgramsAndAChangedGeometryGetsTheNextFree) {
  const core::ToolPath tp = atc_read(
      "TLDATA/MILL,10,5,50,0,0\nLOAD/TOOL,4,ADJUST,4\nFEDRAT/MMPM,100\nGOTO/0,0,0\nGOTO/1,0,0\n"  // 2-6
      "TLDATA/MILL,6,0,30,0,0\nLOAD/TOOL,2\nGOTO/2,0,0\n"                                         // 7-9
      "TLDATA/MILL,3,1.5,20,0,0\nGOTO/3,0,0\n");  // 10-11: tool 2's number, another geometry
  EXPECT_EQ(atc_numbers(tp), (std::vector<int>{4, 2, 5}));
  ASSERT_EQ(tp.program_tools.size(), 3u);
  EXPECT_TRUE(tp.program_tools[0].numbered_by_program);
  EXPECT_TRUE(tp.program_tools[1].numbered_by_program);
  EXPECT_FALSE(tp.program_tools[2].numbered_by_program);
  EXPECT_EQ(tp.program_tools[2].diameter_mm, 3.0);
  ASSERT_EQ(tp.warnings.size(), 1u);
  EXPECT_NE(tp.warnings[0].find("tc.cls:10:"), std::string::npos) << tp.warnings[0];
  EXPECT_NE(tp.warnings[0].find("numbered 5"), std::string::npos) << tp.warnings[0];
}

// ---- the real NX file ------------------------------------------------------------------------------------------

fs::path atc_project2() {
  return fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "cam" / "nx_clsf_haas_umc750" / "APT_Project2.txt";
}

// Per line of the file, the LOAD/TOOL number and the TLDATA/ text (d, r, length) in force there: a plain scan.
struct AtcInForce {
  std::vector<int> load;
  std::vector<std::string> tldata;
  std::vector<int> tldata_line;
};
AtcInForce atc_scan(const fs::path& file) {
  AtcInForce f;
  std::ifstream in(file);
  std::string line, tl;
  int load = 0, tl_line = 0, n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (line.rfind("TLDATA/MILL,", 0) == 0) {
      // d, r, length: the first three values after MILL.
      std::size_t p = 12;
      for (int k = 0; k < 3; ++k) p = line.find(',', p) + 1;
      tl = line.substr(12, p - 13);
      tl_line = n;
    }
    if (line.rfind("LOAD/TOOL,", 0) == 0) load = std::stoi(line.substr(10));
    f.load.push_back(load);
    f.tldata.push_back(tl);
    f.tldata_line.push_back(tl_line);
  }
  return f;
}

// Each move's tool is the LOAD/TOOL number in force at its line, and that tool's geometry is the TLDATA/ in force
// there, in inch (no UNITS/: the job's program_units). The three tools of the file (a scan of its TLDATA/ and
// LOAD/TOOL lines by grep): T1 D0.75 R0.12 L4 from line 8 and again from 4732, T2 D0.375 flat L1.5 from 4627, T3
// D0.24 R0.12 (a ball) L2.5 from 5318.
TEST(AptToolChangesReal, Project2ToolsTheirLinesAndMoves) {
  const fs::path file = atc_project2();
  if (!fs::exists(file)) GTEST_SKIP() << file << " is absent (the real CAM programs of ../shared)";
  ProgramOptions o;
  o.program_units = LengthUnit::Inch;
  const core::ToolPath tp = read_program(file, o);
  constexpr double in = core::units::kInchToMm;
  ASSERT_EQ(tp.program_tools.size(), 3u);
  struct Expected {
    int number;
    double d, r, l;
    std::vector<int> stretches;
  };
  const Expected expected[3] = {
      {1, 0.75, 0.12, 4.0, {8, 4732}}, {2, 0.375, 0.0, 1.5, {4627}}, {3, 0.24, 0.12, 2.5, {5318}}};
  std::map<int, const core::ProgramTool*> by_number;
  for (int k = 0; k < 3; ++k) {
    const core::ProgramTool& t = tp.program_tools[static_cast<std::size_t>(k)];
    EXPECT_EQ(t.number, expected[k].number);
    EXPECT_NEAR(t.diameter_mm, expected[k].d * in, 1e-9);
    EXPECT_NEAR(t.corner_radius_mm, expected[k].r * in, 1e-9);
    EXPECT_NEAR(t.length_mm, expected[k].l * in, 1e-9);
    EXPECT_EQ(t.stretch_lines, expected[k].stretches) << "tool " << t.number;
    EXPECT_TRUE(t.numbered_by_program);
    by_number[t.number] = &t;
  }
  for (const std::string& w : tp.warnings) ADD_FAILURE() << w;
  const AtcInForce f = atc_scan(file);
  std::map<int, int> moves, first_line, last_line;
  for (const core::Move& m : tp.moves) {
    const auto l = static_cast<std::size_t>(m.source_line - 1);
    ASSERT_EQ(m.tool_number, f.load.at(l)) << "line " << m.source_line;
    const core::ProgramTool& t = *by_number.at(m.tool_number);
    char text[64];
    std::snprintf(text, sizeof text, "%.4f,%.4f,%.4f", t.diameter_mm / in, t.corner_radius_mm / in, t.length_mm / in);
    ASSERT_EQ(f.tldata.at(l), text) << "line " << m.source_line;
    ++moves[m.tool_number];
    first_line.emplace(m.tool_number, m.source_line);
    last_line[m.tool_number] = m.source_line;
  }
  EXPECT_EQ(moves.size(), 3u);
  // T2's moves lie between its TLDATA/ (4627) and the next tool's (4732).
  EXPECT_GT(first_line[2], 4627);
  EXPECT_LT(last_line[2], 4732);
  EXPECT_GT(first_line[3], 5318);
  std::printf("[ NX TOOLS ] APT_Project2.txt: T1 %d moves (lines %d..%d), T2 %d (%d..%d), T3 %d (%d..%d)\n", moves[1],
              first_line[1], last_line[1], moves[2], first_line[2], last_line[2], moves[3], first_line[3],
              last_line[3]);
}

}  // namespace
}  // namespace vmsim::program
