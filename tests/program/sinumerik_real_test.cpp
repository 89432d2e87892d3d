// The Sinumerik reader on real NX-posted 840D sl programs: the production data set for five-axis milling with
// changeovers (Zenodo 10.5281/zenodo.15735480, Scientific Data 10.1038/s41597-025-05294-0, CC BY 4.0), programs run
// on a Spinner U5-620, read from ../shared/data/real (skipped when absent).
// References, all from outside vmsim: the files' own text (block counts by a plain scan written here, independent of
// the reader's lexer), the data set's Tool_information.csv (the tools), and the part's geometry as the programs
// themselves state it (the facing operations of the coordinate-system cube).
#include "core/error.hpp"
#include "program/program.hpp"
#include "program/sinumerik.hpp"

#include <gtest/gtest.h>

#include <algorithm>
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

fs::path spinner_dir() { return fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "cam" / "spinner_u5-620_840d"; }

#define SKIP_WITHOUT_840D_DATA() \
  if (!fs::exists(spinner_dir())) GTEST_SKIP() << spinner_dir() << " is absent (the real CAM programs of ../shared)"

const std::vector<int> kSpinnerM = {27, 29, 50, 51, 65};  // Spinner's own M functions in these files, without motion

SinumerikResult read(const std::string& name, bool lenient = false, std::vector<int> mcodes = kSpinnerM) {
  SinumerikOptions o;
  o.no_motion_mcodes = std::move(mcodes);
  o.lenient = lenient;
  return interpret_sinumerik(spinner_dir() / name, o);
}

std::vector<std::string> lines_of(const fs::path& p) {
  std::ifstream in(p);
  std::vector<std::string> out;
  std::string l;
  while (std::getline(in, l)) out.push_back(l);
  return out;
}

// Motion blocks by a plain scan: the code before ';', the motion G word kept modally, a block moves when it names
// an axis (X.. Y.. Z.. B.. C.., or X=..) and is not a frame statement.
struct ScanCounts {
  int rapid = 0, linear = 0, arcs = 0, tool_calls = 0, m6 = 0;
};
ScanCounts spinner_scan(const fs::path& p) {
  ScanCounts c;
  int mode = 0;
  const std::regex g(R"((?:^|\s)G0*([0-3])(?=\s|$))"), axis(R"((?:^|\s)[XYZBC](?:=|-?[0-9.]))"),
      frame(R"(\b(TRANS|ATRANS|ROT|AROT)\b)"), t(R"(T=")"), m6(R"((?:^|\s)M6(?:\s|$))");
  for (std::string l : lines_of(p)) {
    l = l.substr(0, l.find(';'));
    std::smatch m;
    if (std::regex_search(l, m, g)) mode = std::stoi(m[1]);
    if (std::regex_search(l, t)) ++c.tool_calls;
    if (std::regex_search(l, m6)) ++c.m6;
    if (std::regex_search(l, frame) || !std::regex_search(l, axis)) continue;
    (mode == 0 ? c.rapid : mode == 1 ? c.linear : c.arcs) += 1;
  }
  return c;
}

struct Expected {
  std::string file;
  int lines, rapid, linear, arcs, tools, changes;
};
// Counts of the files as `grep -c` and the scan above give them (lines: `wc -l`).
const Expected kFiles[] = {
    {"Coordinate_system_representation_Achskreuz.mpf", 3073, 569, 1341, 696, 4, 5},
    {"Keychain_Schluesselanhaenger.mpf", 644, 29, 489, 58, 2, 3},
    {"Bottle_opener_Flaschenoeffner.txt", 2792, 41, 1098, 1553, 3, 4},
};

TEST(SinumerikReal, CountsOfBlocksArcsAndMovesMatchTheFiles) {
  SKIP_WITHOUT_840D_DATA();
  for (const Expected& e : kFiles) {
    SCOPED_TRACE(e.file);
    const SinumerikResult r = read(e.file);
    const ScanCounts s = spinner_scan(spinner_dir() / e.file);
    EXPECT_EQ(r.stats.lines, e.lines);
    EXPECT_EQ(static_cast<int>(r.stats.blocks), e.lines);  // no jumps: every line runs once
    EXPECT_EQ(r.stats.rapid_blocks, s.rapid);
    EXPECT_EQ(r.stats.linear_blocks, s.linear);
    EXPECT_EQ(r.stats.arc_blocks, s.arcs);
    EXPECT_EQ(r.stats.rapid_blocks, e.rapid);
    EXPECT_EQ(r.stats.linear_blocks, e.linear);
    EXPECT_EQ(r.stats.arc_blocks, e.arcs);
    EXPECT_EQ(static_cast<int>(r.tools.size()), e.tools);
    EXPECT_EQ(r.stats.tool_changes, s.m6);
    EXPECT_EQ(r.stats.tool_changes, e.changes);
    // Every move carries the line that made it, and the moves join.
    for (std::size_t i = 0; i < r.path.moves.size(); ++i) {
      const core::Move& m = r.path.moves[i];
      ASSERT_GT(m.source_line, 0);
      ASSERT_LE(m.source_line, e.lines);
      if (i > 0) {
        ASSERT_LT((m.start - r.path.moves[i - 1].end).cwiseAbs().maxCoeff(), 1e-9) << m.source_line;
      }
    }
    // The program's own tolerance: CYCLE832(_camtolerance, ...) with _camtolerance = .02 for every feed move.
    ASSERT_TRUE(r.contour_tolerance_mm.has_value());
    EXPECT_DOUBLE_EQ(*r.contour_tolerance_mm, 0.02);
    std::printf(
        "[ COUNTS   ] %s: %d lines, %d G0 / %d G1 / %d G2-G3 blocks, %d cycles, %zu ToolPath moves (%d TCP), "
        "%zu canonical calls, tools %zu, %d tool changes\n",
        e.file.c_str(), r.stats.lines, r.stats.rapid_blocks, r.stats.linear_blocks, r.stats.arc_blocks,
        r.stats.cycle_calls, r.path.moves.size(), r.stats.tcp_moves, r.canon.size(), r.tools.size(),
        r.stats.tool_changes);
  }
}

TEST(SinumerikReal, ToolCallsAreTheDataSetsTools) {
  SKIP_WITHOUT_840D_DATA();
  std::set<std::string> known;
  bool header = true;
  for (std::string l : lines_of(spinner_dir() / "Tool_information.csv")) {
    if (header) {
      header = false;
      continue;
    }
    std::string name = l.substr(0, l.find(';'));
    while (!name.empty() && (name.back() == ' ' || name.back() == '\r')) name.pop_back();
    if (!name.empty()) known.insert(name);
  }
  ASSERT_GE(known.size(), 7u);
  std::set<std::string> used;
  for (const Expected& e : kFiles) {
    const SinumerikResult r = read(e.file);
    for (const std::string& t : r.tools) {
      EXPECT_TRUE(known.count(t)) << e.file << ": T=\"" << t << "\" is not in Tool_information.csv";
      used.insert(t);
    }
    // Each SELECT_TOOL names the tool the T word gave (numbered in order of first call).
    for (const CanonCall& c : r.canon)
      if (c.text.rfind("SELECT_TOOL(", 0) == 0) {
        const int n = std::stoi(c.text.substr(12));
        ASSERT_LE(n, static_cast<int>(r.tools.size()));
      }
  }
  // The three programs together call every tool of the table (8 names; the face mill's head and inserts share one).
  EXPECT_EQ(used, known);
  EXPECT_EQ(known.size(), 8u);
}

TEST(SinumerikReal, UnknownStatementsAreNamedWithFileAndLine) {
  SKIP_WITHOUT_840D_DATA();
  for (const Expected& e : kFiles) {
    SCOPED_TRACE(e.file);
    // Without the machine's M functions the first (N80 M9 M50, line 8) stops the reading, named.
    try {
      read(e.file, false, {});
      ADD_FAILURE() << "no error";
    } catch (const core::Error& err) {
      EXPECT_EQ(std::string(err.what()).rfind((spinner_dir() / e.file).string() + ":8: M50:", 0), 0u) << err.what();
    }
    // Lenient: one warning per unknown M function, on the lines that hold them (found by a plain scan).
    const SinumerikResult r = read(e.file, true, {});
    std::vector<std::string> expected;
    const std::vector<std::string> lines = lines_of(spinner_dir() / e.file);
    const std::regex m(R"((?:^|\s)M(27|29|50|51|65)(?=\s|$))");
    for (std::size_t i = 0; i < lines.size(); ++i) {
      const std::string code = lines[i].substr(0, lines[i].find(';'));
      for (auto it = std::sregex_iterator(code.begin(), code.end(), m); it != std::sregex_iterator(); ++it)
        expected.push_back((spinner_dir() / e.file).string() + ":" + std::to_string(i + 1) + ": M" + (*it)[1].str());
    }
    ASSERT_EQ(r.warnings.size(), expected.size());
    for (std::size_t i = 0; i < expected.size(); ++i)
      EXPECT_EQ(r.warnings[i].rfind(expected[i] + ":", 0), 0u) << r.warnings[i];
    // and the same moves as with the functions named
    EXPECT_EQ(r.path.moves.size(), read(e.file).path.moves.size());
  }
}

// The coordinate-system cube: five faces machined 3+2 (TRAORI, AROT frames). The four side facings and the top
// facing cut into a 50 mm blank: each operation's deepest point along its tool axis (the frame's Z) lies 1 mm inside
// the blank's face in that direction (2 mm on top: two passes), and the faces pair up 48 mm apart, centred on the
// same point, in X and in Y. A frame composed in another order or turned the other way puts a face elsewhere.
TEST(SinumerikReal, ThreePlusTwoFacesComeOutWhereTheFramesPutThem) {
  SKIP_WITHOUT_840D_DATA();
  const SinumerikResult r = read("Coordinate_system_representation_Achskreuz.mpf");
  // Operations by their ";Operation : NAME" comments; each operation's tool axis is the frame's Z in force at its
  // first feed move (the frame comments the reader writes; TRANS X0 Y0 Z0 resets the frame at the operation's end).
  struct Op {
    std::string name;
    int first_line = 0;
    Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  };
  std::vector<Op> ops;
  std::vector<std::pair<int, Eigen::Vector3d>> frames;
  const std::regex frame(R"(z axis \(([-0-9.]+), ([-0-9.]+), ([-0-9.]+)\))");
  for (const CanonCall& c : r.canon) {
    const std::size_t k = c.text.find("Operation : ");
    if (k != std::string::npos) ops.push_back({c.text.substr(k + 12, c.text.size() - k - 14), c.source_line, {}});
    std::smatch m;
    if (std::regex_search(c.text, m, frame))
      frames.emplace_back(c.source_line, Eigen::Vector3d(std::stod(m[1]), std::stod(m[2]), std::stod(m[3])));
  }
  for (std::size_t i = 0; i < ops.size(); ++i) {
    const int to = i + 1 < ops.size() ? ops[i + 1].first_line : 1 << 30;
    const auto first_feed = std::find_if(r.path.moves.begin(), r.path.moves.end(), [&](const core::Move& m) {
      return !m.rapid && m.source_line > ops[i].first_line && m.source_line < to;
    });
    ops[i].axis = Eigen::Vector3d::UnitZ();
    for (const auto& [line, z] : frames)
      if (line > ops[i].first_line && first_feed != r.path.moves.end() && line < first_feed->source_line)
        ops[i].axis = z;
  }
  ASSERT_EQ(ops.size(), 25u);
  auto deepest = [&](const std::string& name, Eigen::Vector3d& axis) {
    const auto it = std::find_if(ops.begin(), ops.end(), [&](const Op& o) { return o.name == name; });
    EXPECT_NE(it, ops.end()) << name;
    const int from = it->first_line, to = it + 1 == ops.end() ? 1 << 30 : (it + 1)->first_line;
    axis = it->axis;
    double d = 1e300;
    int n = 0;
    for (const core::Move& m : r.path.moves)
      if (m.source_line > from && m.source_line < to && !m.rapid) {
        d = std::min(d, m.end.head<3>().dot(axis));
        ++n;
        if (name != "PLANEN") {
          EXPECT_TRUE(m.tcp) << name << " line " << m.source_line;
        }
      }
    EXPECT_GT(n, 5) << name;
    return d;
  };
  struct Face {
    const char* op;
    Eigen::Vector3d normal;  // the blank's face the operation's name says it machines
    double blank_level;      // that face of the blank [-50, 0] x [0, 50] x [.., 0] along the normal
    double depth;
  };
  const Face faces[] = {
      {"PLANEN", Eigen::Vector3d::UnitZ(), 0.0, 2.0},          {"X_ACHSE_PLANEN", Eigen::Vector3d::UnitX(), 0.0, 1.0},
      {"Y_ACHSE_PLANEN", Eigen::Vector3d::UnitY(), 50.0, 1.0}, {"PLANEN_REST_1", -Eigen::Vector3d::UnitX(), 50.0, 1.0},
      {"PLANEN_REST_2", -Eigen::Vector3d::UnitY(), 0.0, 1.0},
  };
  std::map<std::string, double> level;
  for (const Face& f : faces) {
    Eigen::Vector3d axis;
    const double d = deepest(f.op, axis);
    level[f.op] = d;
    EXPECT_LT((axis - f.normal).norm(), 1e-4) << f.op << " tool axis " << axis.transpose();
    EXPECT_NEAR(f.blank_level - d, f.depth, 1e-9) << f.op;
    std::printf("[ FACE     ] %-15s tool axis (%g, %g, %g): deepest %.3f mm along it, %.3f mm into the blank\n", f.op,
                axis.x(), axis.y(), axis.z(), d, f.blank_level - d);
  }
  // Opposite faces 48 mm apart (x from -49 to -1, y from 1 to 49), centred on x = -25, y = 25.
  EXPECT_NEAR(level["X_ACHSE_PLANEN"] + level["PLANEN_REST_1"], 48.0, 1e-9);
  EXPECT_NEAR(level["Y_ACHSE_PLANEN"] + level["PLANEN_REST_2"], 48.0, 1e-9);
  // The chamfers and engravings on the side faces work just below the faced surfaces (0.2 mm for the engraved text,
  // 3 to 5.3 mm for the chamfers and the letters), never above them.
  for (const char* op : {"X_ACHSE_FASE", "Y_ACHSE_FASE", "X_BESCHRIFTUNG", "Y_BESCHRIFTUNG", "WZM", "THWS"}) {
    Eigen::Vector3d axis;
    const double d = deepest(op, axis);
    double face = 0;
    if (std::fabs(axis.x() - 1) < 1e-4)
      face = level["X_ACHSE_PLANEN"];
    else if (std::fabs(axis.y() - 1) < 1e-4)
      face = level["Y_ACHSE_PLANEN"];
    else if (std::fabs(axis.x() + 1) < 1e-4)
      face = level["PLANEN_REST_1"];
    else if (std::fabs(axis.y() + 1) < 1e-4)
      face = level["PLANEN_REST_2"];
    else
      ADD_FAILURE() << op << ": tool axis " << axis.transpose() << " is not a side face's";
    std::printf("[ FACE     ] %-15s tool axis (%g, %g, %g): %.3f mm below its face\n", op, axis.x(), axis.y(), axis.z(),
                face - d);
    EXPECT_GE(face - d, -1e-9) << op;
    EXPECT_LE(face - d, 6.0) << op;
  }
}

TEST(SinumerikReal, ReadProgramChoosesTheDialectOfTheTxtFile) {
  SKIP_WITHOUT_840D_DATA();
  // Bottle_opener_Flaschenoeffner.txt has the extension of G-code files: its content says 840D.
  EXPECT_EQ(program_dialect(spinner_dir() / "Bottle_opener_Flaschenoeffner.txt"), Dialect::Sinumerik);
  ProgramOptions o;
  o.no_motion_mcodes = kSpinnerM;
  const core::ToolPath p = read_program(spinner_dir() / "Bottle_opener_Flaschenoeffner.txt", o);
  EXPECT_EQ(p.moves.size(), read("Bottle_opener_Flaschenoeffner.txt").path.moves.size());
  ASSERT_TRUE(p.program_tolerance_mm.has_value());
  EXPECT_DOUBLE_EQ(*p.program_tolerance_mm, 0.02);
  // The other real programs of ../shared (RS274/NGC from CAMotics) stay G-code.
  const fs::path ngc = fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "cam" / "botomata_bottom.nc";
  if (fs::exists(ngc)) {
    EXPECT_EQ(program_dialect(ngc), Dialect::Rs274ngc);
  }
  const fs::path flower = fs::path(VMSIM_SHARED_DIR) / "data" / "real" / "cam" / "flower_mold.nc";
  if (fs::exists(flower)) {
    EXPECT_EQ(program_dialect(flower), Dialect::Rs274ngc);
  }
}

}  // namespace
}  // namespace vmsim::program
