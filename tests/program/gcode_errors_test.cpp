// The G-code reader refuses what it cannot execute faithfully, and says where: every error names the file,
// the line and the word. Hostile input (endless loops, deep nesting, huge numbers) ends in an error, quickly.
#include "gcode_test_support.hpp"

#include <chrono>
#include <iostream>

namespace vmsim::program::gcode_test {
namespace {

// The error must name file:line and contain every fragment.
void expect_error(const std::string& program, int line, const std::vector<std::string>& fragments,
                  GcodeOptions options = {}) {
  const std::string msg = error_of(program, options);
  ASSERT_FALSE(msg.empty()) << "no error for:\n" << program;
  const std::string where = "test.ngc:" + std::to_string(line) + ": ";
  EXPECT_NE(msg.find(where), std::string::npos) << "expected \"" << where << "\" in: " << msg;
  for (const std::string& f : fragments)
    EXPECT_NE(msg.find(f), std::string::npos) << "expected \"" << f << "\" in: " << msg;
}

TEST(GcodeErrors, UnknownAndUnsupportedCodes) {
  expect_error("G21\nG0 X1\nG12 X1\nM2\n", 3, {"G12", "not a G code"});
  expect_error("G21\nM200\nM2\n", 2, {"M200", "not an M code"});
  expect_error("M101\nM2\n", 1, {"M101", "user-defined", "--no-motion-m"});
  expect_error("G21 F10\nG41 D1\nM2\n", 2, {"G41 (cutter radius compensation) is not supported"});
  expect_error("G42.1 D2\nM2\n", 1, {"G42.1 (cutter radius compensation)"});
  expect_error("G95 F1\nM2\n", 1, {"G95 (feed per revolution) is not supported"});
  expect_error("G38.2 Z-1 F10\nM2\n", 1, {"G38.2 (probing)"});
  expect_error("G84 X1 Z-1 R1 F10\nM2\n", 1, {"G84 (canned cycle) is not supported"});
  expect_error("G33 Z-1 K1\nM2\n", 1, {"G33"});
  expect_error("G10 L1 P1 Z1\nM2\n", 1, {"G10 L1 (tool table editing) is not supported"});
  expect_error("M66 P0\nM2\n", 1, {"M66", "not supported"});
  expect_error("G0 U1\nM2\n", 1, {"U word", "not supported"});
  expect_error("G1 X1 E2 F1\nM2\n", 1, {"E word"});
}

TEST(GcodeErrors, WordsAndModalGroups) {
  expect_error("G0 X1 X2\nM2\n", 1, {"two X words"});
  expect_error("G0 G1 X1\nM2\n", 1, {"G0 and G1", "same modal group"});
  expect_error("M3 M4\nM2\n", 1, {"M3 and M4", "same modal group"});
  expect_error("M3 M8 M48 M61 Q0 M0\nM2\n", 1, {"more than four M codes"});
  expect_error("X1 Y2\nM2\n", 1, {"axis words without a motion mode"});
  expect_error("G80 X1\nM2\n", 1, {"axis words with G80"});
  expect_error("G0 X1 P2\nM2\n", 1, {"P word with no"});
  expect_error("G0 X1 I2\nM2\n", 1, {"I word with no G2 or G3"});
  expect_error("G0 X1 G92 Y1\nM2\n", 1, {"G92 and G0 both use the axis words"});
  expect_error("G1 X1\nM2\n", 1, {"G1 with a zero feed rate"});
  expect_error("G93 G1 X1 F1\nG1 X2\nM2\n", 2, {"G1 under G93", "F word on every move"});
  expect_error("F-1\nM2\n", 1, {"negative F"});
  expect_error("G4\nM2\n", 1, {"G4 needs a P word"});
  expect_error("G53 G2 X1 I1\nM2\n", 1, {"G53 must be used with G0 or G1"});
  expect_error("G10 L2 P10 X0\nM2\n", 1, {"P must be 0", "to 9"});
}

TEST(GcodeErrors, ArcsWithMissingOrInconsistentWords) {
  expect_error("G21 F100\nG2 X1\nM2\n", 2, {"G2 needs R (radius) or I/J/K (centre) words"});
  expect_error("G21 F100\nG2 X1 I1 R1\nM2\n", 2, {"both R and I/J/K"});
  expect_error("G21 F100\nG17 G2 X1 K1\nM2\n", 2, {"K word in an arc in the XY (G17) plane"});
  expect_error("G21 F100\nG18 G3 X1 J1\nM2\n", 2, {"J word in an arc in the XZ (G18) plane"});
  expect_error("G21 F100\nG19 G3 Y1 I1\nM2\n", 2, {"I word in an arc in the YZ (G19) plane"});
  expect_error("G21 F100\nG90.1 G2 X10 I5\nM2\n", 2, {"J word missing in an absolute-centre arc (G90.1)"});
  expect_error("G21 F100\nG2 Z1 R5\nM2\n", 2, {"X and Y words are both missing"});
  expect_error("G21 F100\nG0 X5\nG2 X5 R2\nM2\n", 3, {"end point is the start point"});
  expect_error("G21 F100\nG2 X10 Y0 I5.1 J0\nM2\n", 2, {"G2: radius to the end differs", "r1=5.1000 r2=4.9000"});
  expect_error("G21 F100\nG2 X10 Y0 R4\nM2\n", 2, {"radius too small to reach the end point"});
  expect_error("G21 F100\nG2 X0 Y0 I0 J0.00001\nM2\n", 2, {"zero-radius arc"});
  expect_error("G21 F100\nG2 X0 Y0 I5 P0\nM2\n", 2, {"P (number of turns) must be 1 or more"});
  expect_error("G21 F100\nG10 L2 P1 R30\nG18 G2 X10 Z0 I5 K0\nM2\n", 3, {"rotated coordinate system"});
}

TEST(GcodeErrors, UnterminatedAndMismatchedOWords) {
  expect_error("G21\no1 while [1]\nG0 X1\nM2\n", 2, {"o1 while (line 2) has no matching o1 endwhile"});
  expect_error("G21\no2 if [1]\nG0 X1\nM2\n", 2, {"o2 if", "no matching o2 endif"});
  expect_error("o<s> sub\nG0 X1\nM2\n", 1, {"o<s> sub", "no matching o<s> endsub"});
  expect_error("o3 do\nG0 X1\nM2\n", 1, {"o3 do", "no matching o3 while"});
  expect_error("o4 repeat [2]\nG0 X1\nM2\n", 1, {"no matching o4 endrepeat"});
  expect_error("G21\no5 endwhile\nM2\n", 2, {"o5 endwhile has no matching opening O-word"});
  expect_error("o1 if [1]\no2 endif\nM2\n", 2, {"o2 endif does not match", "o1 if (line 1)"});
  expect_error("G21\no1 if [1]\no2 while [1]\no1 endif\no2 endwhile\nM2\n", 4,
               {"o1 endif does not match the innermost open block, o2 while (line 3)"});
  expect_error("o6 break\nM2\n", 1, {"o6 break is not inside an o6 loop"});
  expect_error("o<nowhere> call\nM2\n", 1, {"there is no o<nowhere> sub"});
  expect_error("o7 return\nM2\n", 1, {"o7 return is not inside o7 sub"});
  expect_error("o8 sub\no8 endsub\no8 sub\no8 endsub\nM2\n", 3, {"defined twice"});
  expect_error("o9 if [1]\no9 else\no9 else\no9 endif\nM2\n", 3, {"after o9 else"});
  expect_error("G21\no1 call [1\nM2\n", 2, {"o1 call", "expected ']'"});
}

TEST(GcodeErrors, ExpressionsAndParameters) {
  expect_error("G21\n#1 = [1 / 0]\nM2\n", 2, {"setting #1", "division by zero"});
  expect_error("G21\nG0 X[2 / [1 - 1]]\nM2\n", 2, {"X word: division by zero"});
  expect_error("G0 X[5 MOD 0]\nM2\n", 1, {"MOD by zero"});
  expect_error("G21\nG0 X#<nope>\nM2\n", 2, {"X word: named parameter #<nope> is not defined"});
  expect_error("o1 sub\n#<inner> = 1\no1 endsub\no1 call\nG0 X#<inner>\nM2\n", 5, {"#<inner> is not defined"});
  expect_error("G0 X#<_nope>\nM2\n", 1, {"#<_nope> is not defined"});
  expect_error("G0 X#0\nM2\n", 1, {"parameter number #0 is out of range"});
  expect_error("#5601=1\nG0 X#6000\nM2\n", 2, {"#6000 is out of range"});
  expect_error("G0 X#1.5\nM2\n", 1, {"not a whole number"});
  expect_error("#5420 = 1\nM2\n", 1, {"#5420 is read-only"});
  expect_error("#<_x> = 1\nM2\n", 1, {"#<_x> is a read-only predefined parameter"});
  expect_error("G0 X[SQRT[-1]]\nM2\n", 1, {"SQRT is negative"});
  expect_error("G0 X[LN[0]]\nM2\n", 1, {"LN is zero or negative"});
  expect_error("G0 X[ACOS[2]]\nM2\n", 1, {"ACOS is outside"});
  expect_error("G0 X[-8 ** 0.5]\nM2\n", 1, {"non-integer power"});
  expect_error("G0 X[10 ** 400]\nM2\n", 1, {"not a finite number"});
  expect_error("G0 X[FOO[1]]\nM2\n", 1, {"unknown function", "foo"});
  expect_error("G0 X[1 + ]\nM2\n", 1, {"X word"});
  expect_error("G0 X1.5e3\nM2\n", 1, {"E word"});
  expect_error("G0 X1 $\nM2\n", 1, {"unexpected character '$'"});
  expect_error("G0 X1 (open\nM2\n", 1, {"comment is not closed"});
  expect_error("G0 X1 (a (b) c)\nM2\n", 1, {"nested comment"});
  expect_error("G0 X1 N10\nM2\n", 1, {"N word is only allowed at the start"});
  expect_error("#1 5\nM2\n", 1, {"needs '='"});
}

TEST(GcodeErrors, ProgramFramingAndFiles) {
  expect_error("G21\nG0 X1\n", 2, {"ends without M2 or M30"});
  expect_error("%\nG21\nG0 X1\n", 3, {"ends without M2, M30 or a closing '%'"});
  expect_error("G21\n%\nM2\n", 2, {"'%' may only stand alone on the first and the last line"});
  expect_error("G21\n(abort, stop here)\nM2\n", 2, {"program aborted", "stop here"});
  const std::string missing = error_of("", {}, "x.ngc");  // an empty file is a program without M2
  EXPECT_NE(missing.find("ends without M2"), std::string::npos) << missing;
  try {
    interpret_gcode("/nonexistent/dir/prog.ngc");
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/dir/prog.ngc: cannot open"), std::string::npos) << e.what();
  }
}

TEST(GcodeErrors, ToolsAndToolTables) {
  TempDir dir;
  GcodeOptions options;
  options.tool_table = dir.write("t.tbl", "T1 P1 Z10 D6\nT2 P2 Zx\n");
  try {
    run("M2\n", options);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("t.tbl:2: tool table field \"Zx\" is not a number"), std::string::npos)
        << e.what();
  }
  options.tool_table = dir.write("u.tbl", "T1 P1 Z10 D6 ;ok\nT1 P2 Z1\n");
  EXPECT_NE(error_of("M2\n", options).find("u.tbl:2: tool T1 is listed twice"), std::string::npos);
  options.tool_table = dir.write("v.tbl", "T1 P1 Z10 D6\n");
  expect_error("G21\nT5 M6\nM2\n", 2, {"T5: tool 5 is not in the tool table"}, options);
  expect_error("G21\nG43 H7\nM2\n", 2, {"G43: tool 7 is not in the tool table"}, options);
  expect_error("T1.5\nM2\n", 1, {"T1.5: the tool number must be a whole number"}, options);
  // Without a table a tool change is fine, but a length offset cannot be known.
  EXPECT_EQ(error_of("T3 M6\nG0 X1\nM2\n"), "");
  expect_error("T3 M6\nG43\nM2\n", 2, {"tool 3 is unknown", "tool table"});
  options.tool_table = dir.write("w.tbl", "T1 P1 X2 Z10 D6\n");
  expect_error("T1 M6\nG43\nM2\n", 2, {"tool offsets along X are not supported"}, options);
}

TEST(GcodeErrors, CannedCycleWords) {
  expect_error("G21 F100\nG81 X1 Z-1\nM2\n", 2, {"G81 needs an R word"});
  expect_error("G21 F100\nG81 X1 R1\nM2\n", 2, {"needs a Z word (hole bottom)"});
  expect_error("G21 F100\nG81 X1 Z5 R1\nM2\n", 2, {"R plane (1.0000) is below the hole bottom Z (5.0000)"});
  expect_error("G21 F100\nG83 X1 Z-5 R1\nM2\n", 2, {"G83 needs a Q word"});
  expect_error("G21 F100\nG83 X1 Z-5 R1 Q-1\nM2\n", 2, {"peck depth Q must be more than 0"});
  expect_error("G21 F100\nG82 X1 Z-5 R1\nM2\n", 2, {"G82 needs a P word"});
  expect_error("G21 F100\nG81 X1 Z-5 R1 L0\nM2\n", 2, {"L (repeats)"});
  expect_error("G21 F100\nG81 X1 Z-5 R1 A10\nM2\n", 2, {"rotary axes"});
  expect_error("G21\nG81 X1 Z-5 R1\nM2\n", 2, {"zero feed rate"});
  expect_error("G21 F1\nG93 G81 X1 Z-5 R1\nM2\n", 2, {"cannot run under G93"});
}

TEST(GcodeErrors, EndlessLoopEndsQuicklyWithAnError) {
  const auto t0 = std::chrono::steady_clock::now();
  expect_error("G21\n#1 = 0\no1 while [1]\n#1 = [#1 + 1]\no1 endwhile\nM2\n", 3, {"possible endless loop"});
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::cout << "[ timing   ] endless while loop stopped after " << seconds << " s (20 million blocks)\n";
  EXPECT_LT(seconds, 30.0);
  // A loop that moves ends at the bound on canonical calls (set low here to keep the test short).
  GcodeOptions options;
  options.max_canon_calls = 10000;
  expect_error("G21 F100\no1 do\nG1 X#1\n#1 = [1 - #1]\no1 while [1]\nM2\n", 3,
               {"canonical calls", "possible endless loop"}, options);
  // Pecks that make no progress (Q far below the resolution of the depth) end the same way.
  expect_error("G21 F100\nG83 X1 Z-5 R1 Q1e-300\nM2\n", 2, {"E word"});
  expect_error("G21 F100\nG83 X1 Z-5 R1 Q[10 ** -300]\nM2\n", 2, {"pecks each", "possible endless loop"}, options);
  // Absurd cycle repeats are refused before they start, with the default bounds.
  const auto t1 = std::chrono::steady_clock::now();
  expect_error("G21 F1\nG81 R1 Z-1 L999999999\nM2\n", 2, {"999999999 holes", "possible endless loop"});
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count(), 1.0);
}

TEST(GcodeErrors, HostileNestingAndRecursion) {
  expect_error("G0 X" + std::string(100000, '[') + "1" + std::string(100000, ']') + "\nM2\n", 1,
               {"nested more than 64 levels"});
  std::string sum = "G0 X[1";
  for (int i = 0; i < 5000; ++i) sum += "+1";
  expect_error(sum + "]\nM2\n", 1, {"more than 1000 nested operations"});
  expect_error("G0 X" + std::string(100000, '-') + "1\nM2\n", 1, {"nested more than 64 levels"});
  expect_error("o1 sub\no1 call\no1 endsub\no1 call\nM2\n", 2, {"nested more than 200 deep"});
  // Binary junk is an error, not a crash.
  std::string junk = "G0 X1\n";
  for (int c = 1; c < 256; ++c) junk += static_cast<char>(c);
  junk += "\nM2\n";
  const std::string msg = error_of(junk);
  EXPECT_NE(msg.find("test.ngc:2: unexpected character"), std::string::npos) << msg;
}

// Issue 18: a bad expression on an O-word repeat, while or if line is reported on that line with its cause, not at
// the block's end as "no matching opening O-word" (LinuxCNC's rs274 reports the line it cannot read, too).
TEST(GcodeErrors, BadExpressionOnAnOWordLineIsReportedThere) {
  for (const std::string head : {"o1 repeat [2 +]", "o1 while [#1 LT]", "o1 if [[1]"}) {
    const std::string closer = head.find("repeat") != std::string::npos  ? "o1 endrepeat"
                               : head.find("while") != std::string::npos ? "o1 endwhile"
                                                                         : "o1 endif";
    const std::string program = "G21\n" + head + "\nG0 X1\n" + closer + "\nM2\n";
    expect_error(program, 2, {});
    const std::string msg = error_of(program, {});
    EXPECT_EQ(msg.find("no matching opening"), std::string::npos) << msg;
  }
}

}  // namespace
}  // namespace vmsim::program::gcode_test
