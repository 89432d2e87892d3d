// NX CLSF (Siemens NX cutter-location source) through the APT reader: small programs checked by hand and analytically,
// and the real NX files of the MECH491 post-processor course project (CC0), read from ../shared/data/real (skipped
// when absent). References, all from outside the reader: the files' own text (record counts by a plain line scan
// written here), the contact points NX printed as `$$ xc,yc,zc` comments (for a ball of radius R, the contact point
// lies on the ball: |CC - (P + R u)| = R with P the tool tip and u the tool axis), the circle equations of tilted
// CIRCLE/ records, and the units and tool-axis rules of issue 24 (never guessed silently).
#include "core/error.hpp"
#include "core/units.hpp"
#include "program/apt.hpp"
#include "program/program.hpp"

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace vmsim::program {
namespace {

namespace fs = std::filesystem;
constexpr double kIn = core::units::kInchToMm;

fs::path nx_dir() { return fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "cam" / "nx_clsf_haas_umc750"; }

#define SKIP_WITHOUT_NX_DATA() \
  if (!fs::exists(nx_dir())) GTEST_SKIP() << nx_dir() << " is absent (the real CAM programs of ../shared)"

std::string nx_error_of(const std::string& text, const AptOptions& o = {}) {
  try {
    read_apt_text(text, "nx.cls", o);
  } catch (const core::Error& e) {
    return e.what();
  }
  return "";
}

bool has_warning(const core::ToolPath& tp, const std::string& part) {
  for (const std::string& w : tp.warnings)
    if (w.find(part) != std::string::npos) return true;
  return false;
}

AptOptions inch() {
  AptOptions o;
  o.default_unit = LengthUnit::Inch;
  return o;
}

// ---- small programs ------------------------------------------------------------------------------------------

TEST(NxClsf, UnitsFromUnitsRecordElseJobElseWarning) {
  const std::string body = "FEDRAT/IPM,10.0\nGOTO/0,0,1\nGOTO/1,0,1\n";
  // Neither UNITS/ nor the job's unit: mm, with a warning naming the job key.
  const core::ToolPath none = read_apt_text(body, "nx.cls");
  EXPECT_NEAR(none.moves.at(0).end[core::kX], 1.0, 1e-12);
  EXPECT_TRUE(has_warning(none, "no UNITS/")) << (none.warnings.empty() ? "" : none.warnings[0]);
  EXPECT_TRUE(has_warning(none, "program_units"));
  // The job's unit, no warning.
  const core::ToolPath job = read_apt_text(body, "nx.cls", inch());
  EXPECT_NEAR(job.moves.at(0).end[core::kX], kIn, 1e-12);
  EXPECT_NEAR(job.moves.at(0).feed_mm_per_min, 10 * kIn, 1e-9);
  EXPECT_TRUE(job.warnings.empty());
  // The file's UNITS/ wins over the job's, with a warning that they differ.
  const core::ToolPath file = read_apt_text("UNITS/MM\n" + body, "nx.cls", inch());
  EXPECT_NEAR(file.moves.at(0).end[core::kX], 1.0, 1e-12);
  EXPECT_TRUE(has_warning(file, "differs from [job] program_units"));
  // UNITS/ agreeing with the job: silent.
  EXPECT_TRUE(read_apt_text("UNITS/INCHES\n" + body, "nx.cls", inch()).warnings.empty());
}

TEST(NxClsf, ToolAxisIsModalUnlessMultaxOff) {
  // NX writes i,j,k only when the axis changes and no MULTAX/ record (issue 24: the axis was taken as +Z).
  const core::ToolPath tp = read_apt_text(
      "UNITS/MM\nFEDRAT/MMPM,100\n"
      "GOTO/0,0,10,0.6,0,0.8\n"  // 3
      "GOTO/10,0,10\n"           // 4: keeps (0.6, 0, 0.8)
      "GOTO/20,0,10\n"           // 5: keeps it
      "MULTAX/OFF\n"
      "GOTO/30,0,10\n",  // 7: 3-axis: TLAXIS's +Z
      "nx.cls");
  ASSERT_EQ(tp.moves.size(), 3u);
  const Eigen::Vector3d tilt(0.6, 0, 0.8);
  EXPECT_TRUE(tp.moves[0].tool_axis_end->isApprox(tilt));
  EXPECT_TRUE(tp.moves[1].tool_axis_start->isApprox(tilt));
  EXPECT_TRUE(tp.moves[1].tool_axis_end->isApprox(tilt));
  EXPECT_TRUE(tp.moves[2].tool_axis_end->isApprox(Eigen::Vector3d::UnitZ()));
}

TEST(NxClsf, InformationListingAndRecordsOfNx) {
  // What NX's information window saves: a tab-separated header, the CLSF, "Tool Path Listing has N lines.".
  const std::string text =
      "\nInformation listing created by\tuser\nDate\t18-Dec-2021 21:07:42\nCurrent work part\tC:\\a b\\p.prt\n"
      "Node name\tlaptop\n\n"
      "TOOL PATH/CAVITY_MILL,TOOL,MILL_0.120RAD\n"                                               // 7
      "TLDATA/MILL,0.7500,0.1200,4.0000,0.0000,0.0000\n"                                         // 8
      "MSYS/0.0000,0.0000,0.0000,1.0000000,0.0000000,0.0000000,0.0000000,1.0000000,0.0000000\n"  // 9
      "$$ centerline data\nPAINT/PATH\nPAINT/SPEED,10\nLOAD/TOOL,1,ADJUST,1\nPAINT/COLOR,186\n"  // 10-14
      "RAPID\nGOTO/2.3600,2.2749,3.5300,0.0000000,0.0000000,1.0000000\n"                         // 15-16
      "FEDRAT/IPM,10.0000\nGOTO/2.3600,2.2749,3.1000 $$ 1,2,3\n"                                 // 17-18
      "PAINT/TOOL,NOMORE\nEND-OF-PATH\nTool Path Listing has 11294 lines.\n";
  EXPECT_TRUE(looks_like_apt(text));
  const core::ToolPath tp = read_apt_text(text, "nx.txt", inch());
  ASSERT_EQ(tp.moves.size(), 1u);
  EXPECT_EQ(tp.moves[0].source_line, 18);
  EXPECT_EQ(tp.moves[0].tool_number, 1);
  EXPECT_NEAR(tp.tool_diameter_mm, 0.75 * kIn, 1e-12);
  EXPECT_NEAR(tp.tool_corner_radius_mm, 0.12 * kIn, 1e-12);
  EXPECT_NEAR(tp.tool_length_mm, 4.0 * kIn, 1e-12);
  EXPECT_EQ(tp.tool_line, 8);
  // A listing line elsewhere, or a misspelt one, is not skipped.
  EXPECT_NE(nx_error_of("UNITS/MM\nInformation listing made by\tx\nGOTO/0,0,0\n").find("nx.cls:2:"), std::string::npos);
  // Unknown records: an error naming file, line and record.
  const std::string e = nx_error_of("UNITS/MM\nGOTO/0,0,0\nFROBNICATE/1,2\n");
  EXPECT_NE(e.find("nx.cls:3:"), std::string::npos) << e;
  EXPECT_NE(e.find("FROBNICATE"), std::string::npos) << e;
  // Not APT: G-code and 840D text.
  EXPECT_FALSE(looks_like_apt("G0 X0 Y0\nG1 Z-1 F100\n"));
  EXPECT_FALSE(looks_like_apt("; NX\nDEF REAL _camtolerance\nG0 X0\n"));
  EXPECT_FALSE(looks_like_apt("/G0 X0\n"));
}

// A later, different TLDATA/ starts a new tool (issue 24: every move is cut by the tool in effect at it; more in
// apt_tool_changes_test.cpp), never silently the first.
TEST(NxClsf, LaterToolsStartNewTools) {
  const core::ToolPath tp = read_apt_text(
      "UNITS/MM\nTLDATA/MILL,10,5,50,0,0\nFEDRAT/MMPM,100\nGOTO/0,0,0\nGOTO/1,0,0\n"
      "TLDATA/MILL,10,5,50,0,0\n"  // 6: the same tool
      "TLDATA/MILL,6,0,30,0,0\n"   // 7: another
      "GOTO/2,0,0\n",
      "nx.cls");
  EXPECT_EQ(tp.tool_diameter_mm, 10.0);
  EXPECT_EQ(tp.tool_line, 2);
  ASSERT_EQ(tp.moves.size(), 2u);
  EXPECT_EQ(tp.moves[0].tool_number, 1);
  EXPECT_EQ(tp.moves[1].tool_number, 2);
  ASSERT_EQ(tp.program_tools.size(), 2u);
  EXPECT_EQ(tp.program_tools[1].line, 7);
  EXPECT_TRUE(tp.warnings.empty());
}

TEST(NxClsf, UnmodelledRecordsAreErrorsOrWarningsWhenLenient) {
  const std::string text = "UNITS/MM\nFEDRAT/MMPM,100\nGOTO/0,0,0\nDELAY/2.0\nCUTCOM/LEFT\nCUTCOM/OFF\nGOTO/1,0,0\n";
  const std::string e = nx_error_of(text);
  EXPECT_NE(e.find("nx.cls:4:"), std::string::npos) << e;
  EXPECT_NE(e.find("DELAY"), std::string::npos) << e;
  EXPECT_NE(e.find("program_lenient"), std::string::npos) << e;
  AptOptions lenient;
  lenient.lenient = true;
  const core::ToolPath tp = read_apt_text(text, "nx.cls", lenient);
  ASSERT_EQ(tp.warnings.size(), 2u);  // DELAY and CUTCOM/LEFT; CUTCOM/OFF is silent
  EXPECT_NE(tp.warnings[0].find("nx.cls:4:"), std::string::npos);
  EXPECT_NE(tp.warnings[1].find("nx.cls:5:"), std::string::npos);
  EXPECT_EQ(tp.moves.size(), 1u);
}

TEST(NxClsf, LaterMsysFrameIsCarriedIntoTheFirst) {
  // Second frame: origin (10, 20, 30) in NX's absolute frame, turned 90 deg about Z (its X along absolute +Y); the
  // first is the absolute frame shifted by (1, 2, 3). A point (1, 0, 0) of the second frame is absolute (10, 21, 30),
  // in the first frame (9, 19, 27); its axis (1, 0, 0) is absolute (0, 1, 0).
  const core::ToolPath tp = read_apt_text(
      "UNITS/MM\nMSYS/1,2,3,1,0,0,0,1,0\nFEDRAT/MMPM,100\nGOTO/0,0,0\n"
      "MSYS/10,20,30,0,1,0,-1,0,0\nGOTO/1,0,0,1,0,0\n",
      "nx.cls");
  ASSERT_EQ(tp.moves.size(), 1u);
  EXPECT_NEAR(tp.moves[0].end[core::kX], 9, 1e-12);
  EXPECT_NEAR(tp.moves[0].end[core::kY], 19, 1e-12);
  EXPECT_NEAR(tp.moves[0].end[core::kZ], 27, 1e-12);
  EXPECT_TRUE(tp.moves[0].tool_axis_end->isApprox(Eigen::Vector3d::UnitY()));
  EXPECT_NE(nx_error_of("MSYS/0,0,0,1,0,0,0.5,0.5,0\n").find("right angles"), std::string::npos);
}

// A CIRCLE/ about a tilted axis: chords whose ends lie on the circle (radius, plane, and the height along the axis
// for a helix), counter-clockwise about the axis, within 1 um of the arc between them, ending on the GOTO/ point.
TEST(NxClsf, TiltedCircleIsInterpolatedInItsOwnPlane) {
  const double t = 30 * core::units::kDegToRad;
  const Eigen::Vector3d n(0, -std::sin(t), std::cos(t)), c(5, 6, 7);
  const Eigen::Vector3d e1(1, 0, 0), e2 = n.cross(e1);  // e1 is in the plane (n.x = 0)
  const double r = 8.0, pitch = 0.5;                    // helix: 0.5 mm along n over the arc
  const double sweep = 250 * core::units::kDegToRad;
  const Eigen::Vector3d start = c + r * e1;
  const Eigen::Vector3d end = c + r * (std::cos(sweep) * e1 + std::sin(sweep) * e2) + pitch * n;
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "UNITS/MM\nFEDRAT/MMPM,100\nGOTO/%.12f,%.12f,%.12f,%.12f,%.12f,%.12f\n"
                "CIRCLE/%.12f,%.12f,%.12f,%.12f,%.12f,%.12f,%.12f,0.006,0.5,16,0\nGOTO/%.12f,%.12f,%.12f\n",
                start.x(), start.y(), start.z(), n.x(), n.y(), n.z(), c.x(), c.y(), c.z(), n.x(), n.y(), n.z(), r,
                end.x(), end.y(), end.z());
  const core::ToolPath tp = read_apt_text(buf, "nx.cls");
  ASSERT_GT(tp.moves.size(), 100u);
  Eigen::Vector3d prev = start;
  double prev_angle = 0, worst_r = 0, worst_h = 0, worst_sag = 0;
  for (std::size_t k = 0; k < tp.moves.size(); ++k) {
    const core::Move& m = tp.moves[k];
    EXPECT_EQ(m.kind, core::MotionKind::Line);
    EXPECT_EQ(m.source_line, 4);  // the CIRCLE/ record's line
    const Eigen::Vector3d p = m.end.head<3>(), d = p - c;
    double a = std::atan2(d.dot(e2), d.dot(e1));
    while (a < prev_angle - 1e-9) a += 2 * core::units::kPi;  // unwrapped: every chord spans far less than pi
    EXPECT_GT(a, prev_angle) << "chord " << k << " does not run counter-clockwise about the axis";
    const double f = a / sweep;
    worst_r = std::max(worst_r, std::abs((d - d.dot(n) * n).norm() - r));
    worst_h = std::max(worst_h, std::abs(d.dot(n) - f * pitch));
    // The arc's point half-way between the chord's ends, against the chord's midpoint.
    const double am = 0.5 * (prev_angle + a);
    const Eigen::Vector3d on_arc = c + r * (std::cos(am) * e1 + std::sin(am) * e2) + (am / sweep) * pitch * n;
    worst_sag = std::max(worst_sag, (on_arc - 0.5 * (prev + p)).norm());
    prev = p;
    prev_angle = a;
  }
  EXPECT_NEAR(prev_angle, sweep, 1e-9);
  EXPECT_LT(worst_r, 1e-9);
  EXPECT_LT(worst_h, 1e-9);
  EXPECT_LT(worst_sag, 1.01e-3);
  EXPECT_LT((tp.moves.back().end.head<3>() - end).norm(), 1e-12);
  std::printf("[ NX CLSF ] tilted helix: %zu chords, radius within %.1e mm, height within %.1e mm, sag %.2f um\n",
              tp.moves.size(), worst_r, worst_h, worst_sag * 1e3);
}

// ---- the real NX files -----------------------------------------------------------------------------------------

struct Scan {
  int gotos = 0, circles = 0, rapids = 0, tldata = 0, loads = 0, zero_length = 0, contact = 0;
  std::set<std::string> tools;      // TLDATA/ argument text
  int tool_changes_from_first = 0;  // TLDATA/ records whose d, r differ from the first one's
};

// A plain scan of the file's lines, independent of the reader: record words at the start of a line, a GOTO/ whose
// x, y, z text repeats the last GOTO/'s (and gives no new axis) counted as zero-length.
Scan nx_scan(const fs::path& file) {
  Scan s;
  std::ifstream in(file);
  std::string line, last_xyz, first_dr;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.rfind("GOTO/", 0) == 0) {
      ++s.gotos;
      std::string rec = line.substr(5);
      if (rec.find("$$") != std::string::npos) {
        ++s.contact;
        rec = rec.substr(0, rec.find("$$"));
      }
      while (!rec.empty() && rec.back() == ' ') rec.pop_back();
      int commas = 0;
      std::size_t third = std::string::npos;
      for (std::size_t i = 0; i < rec.size(); ++i)
        if (rec[i] == ',' && ++commas == 3) third = i;
      const std::string xyz = rec.substr(0, third);
      if (commas == 2 && xyz == last_xyz) ++s.zero_length;
      last_xyz = xyz;
    } else if (line.rfind("CIRCLE/", 0) == 0) {
      ++s.circles;
    } else if (line == "RAPID") {
      ++s.rapids;
    } else if (line.rfind("TLDATA/", 0) == 0) {
      ++s.tldata;
      s.tools.insert(line);
      const std::string dr = line.substr(0, line.find(',', line.find(',', 12) + 1));
      if (first_dr.empty()) first_dr = dr;
      if (dr != first_dr) ++s.tool_changes_from_first;
    } else if (line.rfind("LOAD/TOOL", 0) == 0) {
      ++s.loads;
    }
  }
  return s;
}

struct FileCase {
  const char* name;
  int gotos, circles, rapids, tldata, distinct_tools;  // as written in the data's README and by grep, for the record
};

class NxReal : public ::testing::TestWithParam<FileCase> {};

TEST_P(NxReal, RecordCountsMatchAPlainScan) {
  SKIP_WITHOUT_NX_DATA();
  const FileCase fc = GetParam();
  const fs::path file = nx_dir() / fc.name;
  EXPECT_EQ(program_dialect(file), Dialect::Apt) << "a .txt NX listing is read as APT by its content";
  const Scan s = nx_scan(file);
  EXPECT_EQ(s.gotos, fc.gotos);
  EXPECT_EQ(s.circles, fc.circles);
  EXPECT_EQ(s.rapids, fc.rapids);
  EXPECT_EQ(s.tldata, fc.tldata);
  EXPECT_EQ(static_cast<int>(s.tools.size()), fc.distinct_tools);

  ProgramOptions o;
  o.program_units = LengthUnit::Inch;
  const core::ToolPath tp = read_program(file, o);
  // Moves by the record that made them: every CIRCLE/ one arc (or its chords), every RAPID one rapid move, every
  // other GOTO/ one line except the first (the start) and the zero-length ones.
  std::map<int, int> per_line;
  int rapids = 0;
  for (const core::Move& m : tp.moves) {
    ++per_line[m.source_line];
    if (m.rapid) ++rapids;
  }
  std::vector<std::string> lines;
  {
    std::ifstream in(file);
    std::string l;
    while (std::getline(in, l)) lines.push_back(l);
  }
  int circle_lines = 0, goto_lines = 0;
  for (const auto& [line, count] : per_line) {
    const std::string& text = lines.at(static_cast<std::size_t>(line - 1));
    if (text.rfind("CIRCLE/", 0) == 0)
      ++circle_lines;
    else if (text.rfind("GOTO/", 0) == 0) {
      ++goto_lines;
      EXPECT_EQ(count, 1) << "line " << line;
    } else
      ADD_FAILURE() << "a move from line " << line << ": " << text;
  }
  EXPECT_EQ(circle_lines, s.circles);
  EXPECT_EQ(rapids, s.rapids - (fc.gotos > 0 ? 1 : 0)) << "the first RAPID GOTO/ is the start position";
  EXPECT_EQ(goto_lines, s.gotos - s.circles - 1 - s.zero_length);
  // Tools: the first TLDATA/ is the program's tool; one program tool per distinct TLDATA/ (these files' LOAD/TOOL
  // numbers match their geometries), without a warning.
  EXPECT_EQ(static_cast<int>(tp.program_tools.size()), fc.distinct_tools);
  EXPECT_TRUE(tp.warnings.empty()) << tp.warnings.front();
  EXPECT_GT(tp.tool_diameter_mm, 0.0);
  EXPECT_FALSE(has_warning(tp, "no UNITS/"));
  std::printf("[ NX CLSF ] %s: %d GOTO/, %d CIRCLE/, %d RAPID, %d TLDATA/ (%zu tools), %d zero-length -> %zu moves\n",
              fc.name, s.gotos, s.circles, s.rapids, s.tldata, s.tools.size(), s.zero_length, tp.moves.size());
}

INSTANTIATE_TEST_SUITE_P(Files, NxReal,
                         ::testing::Values(FileCase{"APT_Project2.txt", 10585, 146, 98, 15, 3},
                                           FileCase{"APT_Variable_Axis.txt", 348, 0, 3, 1, 1},
                                           FileCase{"APT_code.txt", 325, 0, 4, 1, 1}),
                         [](const auto& info) {
                           std::string n = info.param.name;
                           return n.substr(0, n.find('.'));
                         });

TEST(NxReal, NoUnitsAnywhereIsAWarning) {
  SKIP_WITHOUT_NX_DATA();
  const core::ToolPath tp = read_program(nx_dir() / "APT_code.txt");
  EXPECT_TRUE(has_warning(tp, "no UNITS/"));
}

// The 2 445 GOTO/s of APT_Project2.txt that carry NX's cutter-contact point (`$$ xc,yc,zc`, the ball-nose operations,
// tool D0.24 in R0.12 in): the contact point lies on the ball whose centre is the tip plus R along the tool axis. The
// axis of these GOTO/s is modal (none of them gives i,j,k): with the axis taken as +Z the invariant fails.
TEST(NxReal, ContactPointsLieOnTheBall) {
  SKIP_WITHOUT_NX_DATA();
  const fs::path file = nx_dir() / "APT_Project2.txt";
  std::map<int, Eigen::Vector3d> contact;  // line -> CC (inch)
  {
    std::ifstream in(file);
    std::string l;
    int n = 0;
    const std::regex re(R"(^GOTO/[^$]*\$\$\s*([-0-9.]+),([-0-9.]+),([-0-9.]+)\s*$)");
    while (std::getline(in, l)) {
      ++n;
      if (!l.empty() && l.back() == '\r') l.pop_back();
      std::smatch m;
      if (std::regex_match(l, m, re)) contact[n] = Eigen::Vector3d(std::stod(m[1]), std::stod(m[2]), std::stod(m[3]));
    }
  }
  ASSERT_EQ(contact.size(), 2445u);
  ProgramOptions o;
  o.program_units = LengthUnit::Inch;
  const core::ToolPath tp = read_program(file, o);
  const double r = 0.12 * kIn;
  // Printed precision: 4 decimals of an inch on P and CC (half a unit each, per coordinate), 7 on the axis.
  const double tol = 2 * std::sqrt(3.0) * 0.00005 * kIn + r * 1e-6;
  int checked = 0, tilted = 0;
  double worst = 0;
  for (const core::Move& m : tp.moves) {
    auto it = contact.find(m.source_line);
    if (it == contact.end()) continue;
    const Eigen::Vector3d u = m.tool_axis_end->normalized();
    const Eigen::Vector3d centre = m.end.head<3>() + r * u;
    const double err = std::abs((it->second * kIn - centre).norm() - r);
    worst = std::max(worst, err);
    if (u.z() < 0.999) ++tilted;
    ++checked;
  }
  EXPECT_GT(checked, 2400);  // the rest are zero-length moves the reader drops
  EXPECT_GT(tilted, 1000) << "the modal tool axis of these GOTO/s is tilted";
  EXPECT_LT(worst, tol);
  std::printf(
      "[ NX CLSF ] contact invariant on %d GOTO/s (%d tilted): | |CC - (P + R u)| - R | <= %.2f um "
      "(printed precision %.2f um)\n",
      checked, tilted, worst * 1e3, tol * 1e3);
}

}  // namespace
}  // namespace vmsim::program
