// The G-code reader against a freshly run LinuxCNC interpreter, `rs274 -g` (Debian package linuxcnc-uspace):
// hand-written programs covering the dialect and seeded random ones, compared line for line. The tests skip
// when /usr/bin/rs274 is not installed; the reference files of gcode_reference_test do not need it.
//
// Known, deliberate differences (not exercised here): rs274 standalone re-reads the position from its canon
// layer after M6/M61 (a point that ignores offset changes since the last move); vmsim keeps the interpreter's
// own position. G28/G30 and G28.1 under an XY rotation use the rotated machine point. Cutter compensation,
// which rs274 executes, is refused.
#include "gcode_test_support.hpp"

#include <cmath>
#include <numbers>
#include <cstdio>
#include <iostream>
#include <random>
#include <sstream>

namespace vmsim::program::gcode_test {
namespace {

const fs::path kRs274 = "/usr/bin/rs274";

#define SKIP_WITHOUT_RS274() \
  if (!fs::exists(kRs274)) GTEST_SKIP() << kRs274.string() << " is not installed (apt-get install linuxcnc-uspace)"

// rs274's own tool table of inch tools (tool_common.tbl): rs274 standalone reads tables as inches.
const char* kInchToolTable =
    "T1 P1 D0.125000 Z+0.511000 ;1/8 end mill\n"
    "T2 P2 D0.062500 Z+0.100000 ;1/16 end mill\n"
    "T3 P3 D0.201000 Z+1.273000 ;#7 tap drill\n";

struct Rs274Run {
  std::vector<std::string> lines;  // stdout
  std::string error;               // stderr without its "executing" line
};

Rs274Run run_rs274(const fs::path& program, const fs::path* table, const TempDir& dir) {
  const fs::path err = dir.path() / "rs274.err";
  const auto quoted = [](const fs::path& p) {
    std::string q(1, '\'');
    q += p.string();
    q += '\'';
    return q;
  };
  // rs274 keeps its tool table in $HOME/.tool.mmap, truncated at start: two runs sharing a HOME (ctest -j)
  // crash each other with SIGBUS. Each run gets the test's own folder as HOME.
  std::string cmd = "HOME=" + quoted(dir.path()) + " " + kRs274.string();
  cmd += " -g ";
  if (table != nullptr) {
    cmd += "-t ";
    cmd += quoted(*table);
    cmd += ' ';
  }
  cmd += quoted(program);
  cmd += " 2>";
  cmd += quoted(err);
  Rs274Run run;
  FILE* pipe = ::popen(cmd.c_str(), "r");
  if (pipe == nullptr) return run;
  std::string line;
  char buf[4096];
  while (std::fgets(buf, sizeof buf, pipe) != nullptr) {
    line += buf;
    if (!line.empty() && line.back() == '\n') {
      line.pop_back();
      run.lines.push_back(line);
      line.clear();
    }
  }
  ::pclose(pipe);
  std::ifstream in(err);
  std::string e;
  while (std::getline(in, e))
    if (e != "executing") run.error += e + "\n";
  return run;
}

// Runs both; if rs274 stops with an error vmsim must refuse the program too, else the listings must be equal.
// `compared` counts the canonical calls found equal (0 when both refused the program).
void compare(const std::string& name, const std::string& text, bool inch_machine, bool with_table,
             std::size_t& compared) {
  compared = 0;
  TempDir dir;
  const fs::path program = dir.write(name + ".ngc", text);
  const fs::path table = dir.write("tools.tbl", kInchToolTable);
  const Rs274Run ref = run_rs274(program, with_table ? &table : nullptr, dir);
  GcodeOptions options;
  options.inch_machine = inch_machine;
  if (with_table) options.tool_table = table;
  GcodeResult mine;
  try {
    mine = interpret_gcode(program, options);
  } catch (const core::Error& e) {
    EXPECT_FALSE(ref.error.empty()) << name << ": vmsim refused a program rs274 runs: " << e.what() << "\n" << text;
    return;
  }
  ASSERT_TRUE(ref.error.empty()) << name << ": rs274 refused a program vmsim runs: " << ref.error << "\n" << text;
  ASSERT_EQ(mine.canon.size(), ref.lines.size()) << name << "\n" << text;
  for (std::size_t i = 0; i < ref.lines.size(); ++i)
    ASSERT_EQ(format_canon_line(static_cast<int>(i + 1), mine.canon[i]), ref.lines[i]) << name << " line " << i + 1;
  compared = ref.lines.size();
  // The ToolPath is continuous when no tool length offset changes (each move starts where the last ended).
  if (!with_table) {
    for (std::size_t i = 1; i < mine.path.moves.size(); ++i)
      ASSERT_LT((mine.path.moves[i].start - mine.path.moves[i - 1].end).norm(), 1e-9) << name << " move " << i;
  }
}

struct Program {
  const char* name;
  const char* text;
  bool inch_machine;
  bool tool_table;
};

// Written while developing against rs274 2.9: arcs in all planes, cycles, offsets, subroutines, inverse time,
// inches, expressions, comments and N words.
const Program kPrograms[] = {
    {"a1", R"ngc(G21 G17 F100
G0 X0 Y0 Z0
G18 G2 X10 Z0 I5 K0
G2 X0 Z0 R5
G19 G3 Y5 Z5 J0 K5
G3 Y0 Z0 J-2.5 K-2.5 X3 P2
G17 G91 G2 X10 Y0 I5
G90.1 G90 G2 X3 Y0 I8 J0
G2 X13 Y0 I8 J0
G91.1
G20 G2 X0.5118 Y0 I-0.1 J0 F4
G21 G0 X10
G2 X10 Y0 I5 J0.01
G2 X0 Y0 I-5 J0.03
G3 A90 X0 Y0 I5 J0
M2
)ngc",
     false, false},
    {"cyc", R"ngc(G21 G17 G90 F100
G0 X0 Y0 Z10
G98 G81 X1 Y2 Z-3 R2
X5
G99 X6 Y7
G91 G98 G81 X2 Y1 Z-4 R-3 L3
G90 G80
G0 Z10
G83 X1 Y1 Z-5 R1 Q2
G73 X2 Y1 Z-5 R1 Q2
G82 X3 Z-1 R1 P0.5
G85 X4 Z-1 R1
G89 X5 Z-1 R1 P0.25
G80
G18 G81 X1 Y-2 Z2 R3
G19 G81 X1 Y2 Z3 R4
G17 G80 G0 Z1
G81 X0 Y0 Z-1 R5
M2
)ngc",
     false, false},
    {"cy2", R"ngc(F10 G0 Z10
G99 G81 X1 Z-3 R5
X2 R2
G98 X3 R1
M2
)ngc",
     false, false},
    {"misc", R"ngc(G21 G90 F200
G0 X0 Y0 Z5
G17 G2 X10 Y0 R5 Z-1
G18 G3 X0 Z-1 R5
G19 G2 Y5 Z4 R5
G17 G91 G1 X1 Y1
G2 X2 Y0 I1 J0
G90 G0 X0 Y0 Z0
G2 X0 Y0 I5 J5 P2 Z-5
G3 I2 J0
G91.1 G18 G2 X3 Z-5 I1.5 K0
G19 G3 Y2 Z-5 J1 K0
G17
#1 = 2
#2 = [#1 * 3]
G1 X[#2 + 1] Y[SIN[30]*10] Z[COS[60]]
G1 X[SQRT[16]] Y[ABS[-3]] Z[EXP[0]]
G1 X[LN[1]] Y[TAN[45]] Z[ASIN[1]]
G1 X[ACOS[0]] Y[ATAN[1]/[-1]] Z[FUP[0.2]]
G1 X[1 + 2 * 3 ** 2 / 6 - 1] Y[[1 + 2] * 3] Z[2 ** 0.5]
G1 X[5 GT 3 AND 2 LT 1 OR 1] Y[1 XOR 1] Z[4 MOD 2.5]
G1 X[1 NE 2] Y[2 GE 2] Z[2 LE 1]
##1 = 7
G1 X#2 Y#[1+1]
G1 X[#1]
G0 X0 Y0 Z0
G92 X10 Y10
G0 X11 Y11
G92.1
G0 X1
G52 X1 Y2
G0 X0 Y0
G52 X0 Y0
G0 X0
G10 L2 P1 R45
G0 X1 Y0
G2 X0 Y1 R1
G10 L2 P1 R0
G0 X2
M2
)ngc",
     false, false},
    {"sub", R"ngc(o<square> sub
  (debug, in sub #1 #2 #<_value>)
  #<local> = [#1 * 2]
  N55 G1 X#<local> Y#2 F100
  o<square> if [#1 GT 2]
    o<square> return [#1*10]
  o<square> endif
o<square> endsub [7]
o100 sub
  #3 = 0
  o101 while [#3 LT #1]
    #3 = [#3 + 1]
    o105 if [#3 EQ 2]
      o101 continue
    o105 endif
    o106 if [#3 EQ 4]
      o101 break
    o106 endif
    G0 Z#3
  o101 endwhile
o100 endsub
G21
o<square> call [1] [2]
(debug, ret #<_value> #<_value_returned>)
o<square> call [3]
(debug, ret #<_value> #<_value_returned>)
o100 call [10]
o102 repeat [2]
  G0 X-1
o102 endrepeat
o104 if [0]
  G0 X100
o104 elseif [1]
  G0 X200
o104 else
  G0 X300
o104 endif
(debug, #<local> #<_x> #5420 #5221)
o200 repeat [3]
  o201 repeat [2]
    G91 G0 X1
  o201 endrepeat
  G90 G0 Y[#5421 + 1]
o200 endrepeat
#<_g> = 5
(debug, #<_g> #<_metric> #<_imperial> #<_absolute> #<_feed> #<_motion_mode> #<_plane> #<_coord_system>)
M2
)ngc",
     false, false},
    {"more1", R"ngc(%
G21 F100 (first) (second)
T3 M6
G43
G10 L2 P1 X5 Y5 Z1 R30
G0 X1 Y1 Z2
G28.1
G0 X2
G30 Z0
G28 X3
G53 G0 X0 Y0
G53 G1 Z-1
G43.1 Z0.7
G0 X1
G43.2 H1
G0 X2
G49
G18 G91 G81 X1 Z1 Y-3 R2 L2
G90 G19 G83 X-4 Y1 Z1 R1 Q0.7
G17 G73 X0 Y0 Z-2 R1 Q0.5 L2
G80 G0 Z5
G10 L2 P1 R0
G18 G2 X4 Z3 R-3
G17
M7
M8
M49
G18
M30
)ngc",
     true, true},
    {"more2", R"ngc(o<fact> sub
  o<fact> if [#1 LE 1]
    o<fact> return [1]
  o<fact> endif
  o<fact> call [#1 - 1]
  o<fact> return [#1 * #<_value>]
o<fact> endsub
o<outer> sub
  #<n> = #1
  o<inner> call [#<n> * 2]
  (debug, outer #<n> inner returned #<_value>)
  G1 X#<_value> F10
o<outer> endsub
o<inner> sub
  o<inner> endsub [#1 + 0.5]
o<fact> call [5]
(debug, 5! = #<_value>)
o<outer> call [3]
#1 = 2
o10 repeat [#1 + 1]
  G91 G1 Y1
o10 endrepeat
G90
o11 while [#1 GT 0]
  #1 = [#1 - 1]
  o12 do
    G1 Z#1
    o12 continue
    G1 Z99
  o12 while [0]
o11 endwhile
/G1 X77
M2
)ngc",
     false, false},
    {"g93", R"ngc(G21 G17
G0 X0 Y0 Z0 A0 C0
G93
G1 X10 F2
G1 A90 F1
G1 X20 C45 F0.5
G2 X30 Y0 R5 F3
G3 X30 Y0 I-5 J0 Z-2 F1
G1 X30 F1
G0 X0
G94 G1 X5 F100
G1 C90
M2
)ngc",
     false, false},
    {"inch", R"ngc(G20 F10
G0 X1 Y1 Z0.5
G1 X2
G2 X3 Y2 R1
G3 X2 Y3 I-1 J0
G81 X1 Y1 Z-0.2 R0.1
G83 X2 Y2 Z-0.5 R0.1 Q0.2
G80
G10 L2 P1 X1 Y1
G0 X0 Y0
G21
G0 X10
G10 L20 P2 X0
G55 G0 X1
G92 X5
G0 X6
G20 G0 X1
G54
M2
)ngc",
     false, false},
    {"w1", R"ngc(G21 F100
G0 X1 Y2 Z3
G10 L2 P2 X10 Y20 Z30
G55
G0 X1 Y1
G10 L2 P2 X5
G10 L20 P1 X0 Y0
G54
G0 X1
G92 X0 Y0 Z0
G0 X1
(debug, #5211 #5212 #5213 #5210)
G92.1
G0 X2
G92 X1
G92.2
G0 X3
G92.3
G0 X4
G59.3 G0 X0
G10 L2 P0 Y7
G10 L2 P9 R30 X1
G0 X5
G91 G0 X1
G90 G53 G0 X0 Y0
M2
)ngc",
     true, false},
    {"t1", R"ngc(G21 G17
T2 M6
G43 H2
G0 X1 Y2 Z3
G43
G49
G0 Z3
S1000 M3
M4
M5
M7
M8
M9
M1
M60
G4 P1.5
G61
G61.1
G64
G64 P0.01 Q0.02
G53 G0 X5
G28
G28.1
G0 X3 Y4
G30
G30.1
G0 X1
G28 Y0
M48
M49
M50 P0
M51
M52
M53
G97
G96 S100 D2000
G97
G94
F10
F10
G1 X3 F10
G93 G1 X4 F2
G1 X5 Y3 Z1 F3
G2 X7 Y5 I2 F4
G1 A30 F2
G94
G1 A40 F100
m30
)ngc",
     true, true},
    {"o2", R"ngc(#5 = 0
o103 do
  #5 = [#5+1]
  G0 Y#5
o103 while [#5 LT 3]
(debug, after #5)
#6 = 0
o107 do
  #6 = [#6+1]
  G0 Y#6
o107 while [#6 LT 3]
M2
)ngc",
     false, false},
    {"o3", R"ngc(o102 repeat [2]
  G0 X-1
o102 endrepeat
#5 = 0
o103 do
  #5 = [#5+1]
  G0 Y#5
o103 while [#5 LT 3]
M2
)ngc",
     false, false},
    {"t3", R"ngc(%
(first) G21 (second)
G0 X1 ; semicolon comment
;only semicolon
  n10 G1 x2 F100
/G1 X99
 / G1 X98
N20G1X3(c)
N0020 G1 X4
N1234567 G1 X5
(MSG, hello there )
(  msg,spaced)
(DEBUG, value #<_x> and #1 and #<undefined>)
#1=5 #2=#1 (debug,#1 #2)
(debug,#1 #2)
G1 X[1+2*3] Y[2**3**2] Z[-2**2]
G1 X[10 MOD 3] Y[-10 MOD 3] Z[1 EQ 1.00001]
G1 X[1 EQ 1.0000001] Y[2 GT 1 AND 0] Z[3 - 2 - 1]
G1 X-[1+1] Y+[2] Z- 3
G1 X[ATAN[1]/[1]] Y[ROUND[2.5]] Z[ROUND[-2.5]]
G1 X[FIX[-1.5]] Y[FUP[-1.5]] Z[EXISTS[#<foo>]]
#<foo> = 3
G1 X[EXISTS[#<foo>]] Y#<foo> Z[#<FOO>+1]
G 1 X 1 . 5 Y # 1

M2
)ngc",
     false, false},
};

TEST(GcodeRs274Live, HandWrittenProgramsMatchLineForLine) {
  SKIP_WITHOUT_RS274();
  std::size_t total = 0;
  for (const Program& p : kPrograms) {
    std::size_t n = 0;
    compare(p.name, p.text, p.inch_machine, p.tool_table, n);
    EXPECT_GT(n, 0u) << p.name << " should run to its end";
    total += n;
  }
  std::cout << "[ compared ] " << std::size(kPrograms) << " programs, " << total
            << " canonical calls equal to rs274's, line for line\n";
}

// Random programs of moves, arcs (R and I/J/K, all planes, helices, turns), cycles, incremental moves,
// parameters, subroutine calls and inverse time, with positions tracked so that every arc is valid.
class RandomProgram {
 public:
  explicit RandomProgram(unsigned seed) : rng_(seed) {}

  std::string make(int lines) {
    out_ << "o<mv> sub\n  G1 X#1 Y#2 Z#3\no<mv> endsub\n";
    out_ << "G21 G17 G90 F200\nG0 X0 Y0 Z5\n";
    for (int i = 0; i < lines; ++i) step();
    out_ << "M2\n";
    return out_.str();
  }

 private:
  double uni(double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng_); }
  int pick(int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng_); }
  static std::string f(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.4f", v);
    return buf;
  }
  void set_pos(double x, double y, double z) {
    x_[0] = std::stod(f(x));
    x_[1] = std::stod(f(y));
    x_[2] = std::stod(f(z));
  }
  std::string xyz(double x, double y, double z) {
    set_pos(x, y, z);
    return " X" + f(x_[0]) + " Y" + f(x_[1]) + " Z" + f(x_[2]);
  }

  void step() {
    switch (pick(11)) {
      case 0:
        out_ << "G0" << xyz(uni(-50, 50), uni(-50, 50), uni(-5, 20)) << "\n";
        break;
      case 1:
        out_ << "G1" << xyz(uni(-50, 50), uni(-50, 50), uni(-5, 20)) << " F" << 10 + pick(2000) << "\n";
        break;
      case 2:
        arc_ijk();
        break;
      case 3:
        arc_r();
        break;
      case 4: {
        static const char* kPlanes[] = {"G17", "G18", "G19"};
        plane_ = pick(3);
        out_ << kPlanes[plane_] << "\n";
        break;
      }
      case 5:
        cycle();
        break;
      case 6: {
        const double dx = uni(-5, 5), dy = uni(-5, 5);
        out_ << "G91 G1 X" << f(dx) << " Y" << f(dy) << "\nG90\n";
        x_[0] += std::stod(f(dx));
        x_[1] += std::stod(f(dy));
        break;
      }
      case 7: {
        const double a = uni(-3, 3), b = uni(1, 4);
        const int deg = pick(360);
        out_ << "#1 = " << f(a) << "\nG1 X[#1 * " << f(b) << " + 10 * SIN[" << deg
             << "]] Y[ABS[#1] ** 2] Z[#1 MOD 2]\n";
        // The generator loses track of X and Y here; go somewhere known.
        out_ << "G0" << xyz(uni(-20, 20), uni(-20, 20), uni(0, 10)) << "\n";
        break;
      }
      case 8: {
        const double x = uni(-30, 30), y = uni(-30, 30), z = uni(0, 10);
        out_ << "o<mv> call [" << f(x) << "] [" << f(y) << "] [" << f(z) << "]\n";
        set_pos(x, y, z);
        break;
      }
      case 9:
        out_ << "G93 G1" << xyz(uni(-50, 50), uni(-50, 50), uni(0, 10)) << " A" << f(uni(-90, 90)) << " F"
             << f(uni(0.5, 20)) << "\nG94 F300\n";
        break;
      case 10:
        out_ << "(note " << pick(1000) << ")\n";
        break;
    }
  }

  // Plane axes: first, second, normal (program axis indices) and their letters, centre-offset letters.
  struct Ax {
    int a, b, c;
    char la, lb, lc, ia, ib;
  };
  Ax axes() const {
    if (plane_ == 1) return {2, 0, 1, 'Z', 'X', 'Y', 'K', 'I'};
    if (plane_ == 2) return {1, 2, 0, 'Y', 'Z', 'X', 'J', 'K'};
    return {0, 1, 2, 'X', 'Y', 'Z', 'I', 'J'};
  }

  void arc_ijk() {
    const Ax ax = axes();
    const double r = uni(1, 20);
    const double start_angle = uni(0, 2 * std::numbers::pi);
    const double ca = x_[ax.a] - r * std::cos(start_angle), cb = x_[ax.b] - r * std::sin(start_angle);
    const bool full = pick(5) == 0;
    const double end_angle = uni(0, 2 * std::numbers::pi);
    double ea = full ? x_[ax.a] : ca + r * std::cos(end_angle);
    double eb = full ? x_[ax.b] : cb + r * std::sin(end_angle);
    const double ec = x_[ax.c] + (pick(2) ? uni(-3, 3) : 0.0);
    std::string line = pick(2) ? "G2" : "G3";
    line += std::string(" ") + ax.la + f(ea) + " " + ax.lb + f(eb) + " " + ax.lc + f(ec);
    line += std::string(" ") + ax.ia + f(ca - x_[ax.a]) + " " + ax.ib + f(cb - x_[ax.b]);
    if (pick(4) == 0) line += " P" + std::to_string(1 + pick(3));
    out_ << line << "\n";
    double p[3] = {x_[0], x_[1], x_[2]};
    p[ax.a] = ea;
    p[ax.b] = eb;
    p[ax.c] = ec;
    set_pos(p[0], p[1], p[2]);
  }

  void arc_r() {
    const Ax ax = axes();
    const double d = uni(1, 30), t = uni(0, 2 * std::numbers::pi);
    const double ea = x_[ax.a] + d * std::cos(t), eb = x_[ax.b] + d * std::sin(t);
    const double r = d / 2 * uni(1.001, 3) * (pick(2) ? 1 : -1);
    out_ << (pick(2) ? "G2 " : "G3 ") << ax.la << f(ea) << " " << ax.lb << f(eb) << " R" << f(r) << "\n";
    double p[3] = {x_[0], x_[1], x_[2]};
    p[ax.a] = ea;
    p[ax.b] = eb;
    set_pos(p[0], p[1], p[2]);
  }

  void cycle() {
    static const char* kCycles[] = {"G81", "G82", "G83", "G73", "G85", "G89"};
    const int k = pick(6);
    const Ax ax = axes();
    const double r = x_[ax.c] - uni(0, 3), bottom = r - uni(1, 10);
    out_ << (pick(2) ? "G98 " : "G99 ") << kCycles[k] << " " << ax.la << f(uni(-20, 20)) << " " << ax.lb
         << f(uni(-20, 20)) << " " << ax.lc << f(bottom) << " R" << f(r);
    if (k == 1 || k == 5) out_ << " P" << f(uni(0, 2));
    if (k == 2 || k == 3) out_ << " Q" << f(uni(0.5, 4));
    if (pick(3) == 0) out_ << " L" << 1 + pick(3);
    out_ << "\n";
    if (pick(2)) out_ << ax.la << f(uni(-20, 20)) << "\n";  // the same cycle at another hole
    out_ << "G80\nG0" << xyz(uni(-20, 20), uni(-20, 20), uni(5, 15)) << "\n";
  }

  std::mt19937 rng_;
  std::ostringstream out_;
  double x_[3] = {0, 0, 5};
  int plane_ = 0;
};

TEST(GcodeRs274Live, SeededRandomProgramsMatchLineForLine) {
  SKIP_WITHOUT_RS274();
  std::size_t total = 0, refused = 0;
  for (unsigned seed = 1; seed <= 40; ++seed) {
    const std::string text = RandomProgram(seed).make(80);
    std::size_t n = 0;
    compare("random" + std::to_string(seed), text, false, false, n);
    total += n;
    refused += n == 0;
  }
  std::cout << "[ compared ] 40 random programs: " << total << " canonical calls equal to rs274's; " << refused
            << " refused by both\n";
  EXPECT_LT(refused, 10u);
}

}  // namespace
}  // namespace vmsim::program::gcode_test
