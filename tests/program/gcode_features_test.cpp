// The G-code reader, feature by feature, on small programs whose results are worked out by hand
// (LinuxCNC's documented behaviour; the values were also checked against `rs274 -g` 2.9 where it applies).
#include "gcode_test_support.hpp"

#include <cmath>
#include <numbers>

namespace vmsim::program::gcode_test {
namespace {

constexpr double kTol = 1e-4;  // canonical calls carry 4 decimals

// Expects the XYZ of the n-th motion call.
void expect_gcode_xyz(const std::vector<Call>& m, std::size_t i, double x, double y, double z) {
  ASSERT_LT(i, m.size());
  ASSERT_GE(m[i].numbers.size(), 3u) << m[i].text;
  EXPECT_NEAR(m[i].numbers[0], x, kTol) << "motion " << i << ": " << m[i].text;
  EXPECT_NEAR(m[i].numbers[1], y, kTol) << "motion " << i << ": " << m[i].text;
  EXPECT_NEAR(m[i].numbers[2], z, kTol) << "motion " << i << ": " << m[i].text;
}

void expect_call(const Call& c, const std::string& name, const std::vector<double>& numbers) {
  EXPECT_EQ(c.name, name) << c.text;
  ASSERT_EQ(c.numbers.size(), numbers.size()) << c.text;
  for (std::size_t k = 0; k < numbers.size(); ++k) EXPECT_NEAR(c.numbers[k], numbers[k], kTol) << c.text << " #" << k;
}

core::Vec6 v6(double x, double y, double z, double a = 0, double b = 0, double c = 0) {
  core::Vec6 v;
  v << x, y, z, a, b, c;
  return v;
}

void expect_vec(const core::Vec6& got, const core::Vec6& want, const std::string& what) {
  EXPECT_LT((got - want).cwiseAbs().maxCoeff(), 1e-9)
      << what << ": got " << got.transpose() << ", want " << want.transpose();
}

// ---------------------------------------------------------------------------------------------------------------
// Expressions

TEST(GcodeExpressions, LinuxCncPrecedenceAndLeftAssociativity) {
  const auto m =
      motions(run("G21 F100\n"
                  "G1 X[1 + 2 * 3] Y[2 ** 3 ** 2] Z[-2 ** 2]\n"     // 7, (2**3)**2 = 64, unary minus binds first: 4
                  "G1 X[10 - 4 - 3] Y[8 / 4 / 2] Z[7 MOD 4 * 2]\n"  // 3, 1, (7 MOD 4) * 2 = 6
                  "G1 X[1 + 2 GT 2] Y[1 LT 2 AND 3 GT 4] Z[0 OR 1 XOR 1]\n"  // 1, 0, (0 OR 1) XOR 1 = 0
                  "G1 X[-10 MOD 3] Y[2 - -3] Z[-[1 + 1]]\n"                  // MOD is never negative: 2; 5; -2
                  "M2\n"));
  ASSERT_EQ(m.size(), 4u);
  expect_gcode_xyz(m, 0, 7, 64, 4);
  expect_gcode_xyz(m, 1, 3, 1, 6);
  expect_gcode_xyz(m, 2, 1, 0, 0);
  expect_gcode_xyz(m, 3, 2, 5, -2);
}

TEST(GcodeExpressions, FunctionsInDegreesRoundingAndComparisonTolerance) {
  const auto m =
      motions(run("G21 F100\n"
                  "G1 X[SIN[30]] Y[COS[60]] Z[TAN[45]]\n"
                  "G1 X[ASIN[1]] Y[ACOS[0]] Z[ATAN[1]/[-1]]\n"
                  "G1 X[SQRT[16]] Y[ABS[-3]] Z[EXP[0]]\n"
                  "G1 X[LN[EXP[2]]] Y[FIX[-1.5]] Z[FUP[-1.5]]\n"
                  "G1 X[ROUND[2.5]] Y[ROUND[-2.5]] Z[EXISTS[#<nope>]]\n"
                  "#<yes> = 1\n"
                  "G1 X[EXISTS[#<yes>]] Y[1 EQ 1.00001] Z[1 EQ 1.001]\n"  // EQ within LinuxCNC's 1e-4
                  "g1 x [ 1 + 1 ] y-2.5 Z.5\n"                            // any case, blanks anywhere
                  "M2\n"));
  ASSERT_EQ(m.size(), 7u);
  expect_gcode_xyz(m, 0, 0.5, 0.5, 1);
  expect_gcode_xyz(m, 1, 90, 90, 135);
  expect_gcode_xyz(m, 2, 4, 3, 1);
  expect_gcode_xyz(m, 3, 2, -2, -1);
  expect_gcode_xyz(m, 4, 3, -3, 0);
  expect_gcode_xyz(m, 5, 1, 1, 0);
  expect_gcode_xyz(m, 6, 2, -2.5, 0.5);
}

// ---------------------------------------------------------------------------------------------------------------
// Parameters

TEST(GcodeParameters, NumberedNamedIndirectAndReadBeforeSet) {
  const auto m =
      motions(run("G21 F100\n"
                  "#1 = 5\n"
                  "#2 = [#1 + 1] #3 = #2\n"  // a line reads every value before it sets any: #3 gets the old #2 (0)
                  "G1 X#2 Y#3 Z#[1 + 1]\n"   // 6, 0, 6
                  "#<a> = 2 #<_g> = 3\n"
                  "#[#<a> + 10] = 7\n"           // #12
                  "G1 X#<a> Y#<_g> Z#12\n"       // 2, 3, 7
                  "##<a> = 9\n"                  // #2 = 9
                  "G1 X#2 Y[#<_g> * 2] Z#<A>\n"  // names are case-insensitive
                  "M2\n"));
  ASSERT_EQ(m.size(), 3u);
  expect_gcode_xyz(m, 0, 6, 0, 6);
  expect_gcode_xyz(m, 1, 2, 3, 7);
  expect_gcode_xyz(m, 2, 9, 6, 2);
}

TEST(GcodeParameters, LocalNamesBelongToTheirCallGlobalsDoNot) {
  const auto m =
      motions(run("o<s> sub\n"
                  "  #<loc> = 1\n"
                  "  #<_glob> = #1\n"
                  "o<s> endsub\n"
                  "G21 F100\n"
                  "#<loc> = 5\n"
                  "#1 = 7\n"
                  "o<s> call [42]\n"
                  "G1 X#<loc> Y#<_glob> Z#1\n"  // the caller's #<loc> and #1 are untouched
                  "M2\n"));
  ASSERT_EQ(m.size(), 1u);
  expect_gcode_xyz(m, 0, 5, 42, 7);
}

TEST(GcodeParameters, PredefinedParametersAndDebugMessages) {
  const GcodeResult r =
      run("G21 F100\n"
          "G1 X1 Y2 Z3\n"
          "(debug, x=#<_x> #5422 metric=#<_metric> feed=#<_feed> undefined=#<nope>)\n"
          "(MSG, plain text #1)\n"
          "M2\n");
  const auto t = texts(r);
  EXPECT_NE(std::find(t.begin(), t.end(),
                      "MESSAGE(\" x=1.000000 3.000000 metric=1.000000 feed=100.000000 undefined=######\")"),
            t.end());
  EXPECT_NE(std::find(t.begin(), t.end(), "MESSAGE(\" plain text #1\")"), t.end());
}

// ---------------------------------------------------------------------------------------------------------------
// O-words

TEST(GcodeOWords, NestedWhileLoops) {
  const auto m =
      motions(run("G21 F100\n"
                  "#1 = 0\n"
                  "o1 while [#1 LT 3]\n"
                  "  #2 = 0\n"
                  "  o2 while [#2 LT 2]\n"
                  "    G1 X#1 Y#2\n"
                  "    #2 = [#2 + 1]\n"
                  "  o2 endwhile\n"
                  "  #1 = [#1 + 1]\n"
                  "o1 endwhile\n"
                  "M2\n"));
  ASSERT_EQ(m.size(), 6u);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 2; ++j) expect_gcode_xyz(m, static_cast<std::size_t>(2 * i + j), i, j, 0);
}

TEST(GcodeOWords, SubroutineArgumentsReturnValuesAndRecursion) {
  const auto m =
      motions(run("o<add> sub\n"
                  "  o<add> return [#1 + #2 + #3]\n"
                  "o<add> endsub\n"
                  "o<fact> sub\n"
                  "  o<fact> if [#1 LE 1]\n"
                  "    o<fact> return [1]\n"
                  "  o<fact> endif\n"
                  "  o<fact> call [#1 - 1]\n"
                  "  o<fact> return [#1 * #<_value>]\n"
                  "o<fact> endsub\n"
                  "G21 F100\n"
                  "#1 = 11\n"
                  "o<add> call [1] [2]\n"                    // #3 not given: 0
                  "G1 X#<_value> Y#<_value_returned> Z#1\n"  // 3, 1, and the caller's #1 is back
                  "o<fact> call [5]\n"
                  "G1 X#<_value>\n"
                  "M2\n"));
  ASSERT_EQ(m.size(), 2u);
  expect_gcode_xyz(m, 0, 3, 1, 11);
  expect_gcode_xyz(m, 1, 120, 1, 11);
}

TEST(GcodeOWords, IfElseifElseRepeatDoWhileBreakContinue) {
  const auto m =
      motions(run("G21 F100\n"
                  "o1 repeat [3]\n"
                  "  G91 G1 X1\n"
                  "o1 endrepeat\n"
                  "G90\n"
                  "#1 = 0\n"
                  "o2 do\n"
                  "  #1 = [#1 + 1]\n"
                  "  o3 if [#1 EQ 2]\n"
                  "    o2 continue\n"
                  "  o3 elseif [#1 EQ 4]\n"
                  "    o2 break\n"
                  "  o3 else\n"
                  "    G1 Y#1\n"
                  "  o3 endif\n"
                  "o2 while [#1 LT 10]\n"
                  "o4 if [0]\n"
                  "  G1 Z100\n"
                  "o4 elseif [1]\n"
                  "  G1 Z7\n"
                  "o4 else\n"
                  "  G1 Z300\n"
                  "o4 endif\n"
                  "M2\n"));
  ASSERT_EQ(m.size(), 6u);
  expect_gcode_xyz(m, 0, 1, 0, 0);
  expect_gcode_xyz(m, 1, 2, 0, 0);
  expect_gcode_xyz(m, 2, 3, 0, 0);
  expect_gcode_xyz(m, 3, 3, 1, 0);
  expect_gcode_xyz(m, 4, 3, 3, 0);
  expect_gcode_xyz(m, 5, 3, 3, 7);
}

TEST(GcodeOWords, SubroutineDefinedAfterTheMainProgramAndNWordsInsideIt) {
  const GcodeResult r =
      run("G21 F100\n"
          "o<late> call\n"
          "M2\n"
          "o<late> sub\n"
          "N55 G1 X3\n"
          "o<late> endsub\n");
  const auto m = motions(r);
  ASSERT_EQ(m.size(), 1u);
  for (const CanonCall& c : r.canon)
    if (c.text.starts_with("STRAIGHT_FEED")) {
      EXPECT_EQ(c.n_word, "N55");
      EXPECT_EQ(c.source_line, 5);
    }
}

// ---------------------------------------------------------------------------------------------------------------
// Arcs and helices

TEST(GcodeArcs, RAndIjkInAllPlanesFullCirclesAndHelicesWithTurns) {
  const GcodeResult r =
      run("G21 G17 F100\n"
          "G0 X0 Y0 Z0\n"
          "G2 X10 Y0 I5 J0\n"          // cw half circle about (5, 0)
          "G3 X10 Y0 I-5 J0 Z-3 P2\n"  // full circle twice, a helix down to Z-3
          "G0 Z0\n"
          "G2 X0 Y0 R5\n"    // R: a semicircle
          "G2 X5 Y5 R5\n"    // R > 0: the short arc, centre (5, 0)
          "G2 X10 Y0 R-5\n"  // R < 0: the long arc, centre (10, 5)
          "G18 G0 X0 Y0 Z0\n"
          "G2 X10 Z0 I5 K0\n"  // XZ: ARC_FEED(z, x, cz, cx, ...), centre (z 0, x 5)
          "G3 Z0 X0 R5 Y2\n"   // helix along Y
          "G19 G0 X0 Y0 Z0\n"
          "G2 Y0 Z10 J0 K5\n"  // YZ: ARC_FEED(y, z, cy, cz, ...)
          "G3 Y0 Z0 J0 K-5 X4 P3\n"
          "M2\n");
  const auto m = motions(r);
  ASSERT_EQ(m.size(), 13u);
  expect_call(m[1], "ARC_FEED", {10, 0, 5, 0, -1, 0, 0, 0, 0});
  expect_call(m[2], "ARC_FEED", {10, 0, 5, 0, 2, -3, 0, 0, 0});
  expect_call(m[4], "ARC_FEED", {0, 0, 5, 0, -1, 0, 0, 0, 0});
  expect_call(m[5], "ARC_FEED", {5, 5, 5, 0, -1, 0, 0, 0, 0});
  expect_call(m[6], "ARC_FEED", {10, 0, 10, 5, -1, 0, 0, 0, 0});
  expect_call(m[8], "ARC_FEED", {0, 10, 0, 5, -1, 0, 0, 0, 0});
  expect_call(m[9], "ARC_FEED", {0, 0, 0, 5, 1, 2, 0, 0, 0});
  expect_call(m[11], "ARC_FEED", {0, 10, 0, 5, -1, 0, 0, 0, 0});
  expect_call(m[12], "ARC_FEED", {0, 0, 0, 5, 3, 4, 0, 0, 0});

  // The ToolPath carries the same arcs (mm, no offsets here): plane, centre, turns, helix ends.
  std::vector<const core::Move*> arcs;
  for (const core::Move& mv : r.path.moves)
    if (mv.kind == core::MotionKind::Arc) arcs.push_back(&mv);
  ASSERT_EQ(arcs.size(), 9u);
  const core::Move& helix = *arcs[1];
  EXPECT_EQ(helix.plane, core::ArcPlane::XY);
  EXPECT_EQ(helix.rotation, 2);
  EXPECT_NEAR(helix.centre_mm.x(), 5, 1e-12);
  EXPECT_NEAR(helix.centre_mm.y(), 0, 1e-12);
  expect_vec(helix.start, v6(10, 0, 0), "helix start");
  expect_vec(helix.end, v6(10, 0, -3), "helix end");
  EXPECT_FALSE(helix.rapid);
  EXPECT_DOUBLE_EQ(helix.feed_mm_per_min, 100.0);
  EXPECT_NEAR(arcs[4]->centre_mm.x(), 10, 1e-9);
  EXPECT_NEAR(arcs[4]->centre_mm.y(), 5, 1e-9);
  EXPECT_EQ(arcs[5]->plane, core::ArcPlane::ZX);
  EXPECT_NEAR(arcs[5]->centre_mm.x(), 0, 1e-12);  // z
  EXPECT_NEAR(arcs[5]->centre_mm.y(), 5, 1e-12);  // x
  EXPECT_EQ(arcs[8]->plane, core::ArcPlane::YZ);
  EXPECT_EQ(arcs[8]->rotation, 3);
  expect_vec(arcs[8]->end, v6(4, 0, 0), "YZ helix end");
}

TEST(GcodeArcs, AbsoluteAndIncrementalArcCentres) {
  const auto m =
      motions(run("G21 F100\n"
                  "G0 X10 Y0\n"
                  "G90.1 G2 X0 Y0 I5 J0\n"   // centre at (5, 0)
                  "G91.1 G3 X10 Y0 I5 J0\n"  // centre 5 to the right of the start (0, 0)
                  "M2\n"));
  ASSERT_EQ(m.size(), 3u);
  expect_call(m[1], "ARC_FEED", {0, 0, 5, 0, -1, 0, 0, 0, 0});
  expect_call(m[2], "ARC_FEED", {10, 0, 5, 0, 1, 0, 0, 0, 0});
}

TEST(GcodeArcs, LinuxCncArcToleranceRules) {
  // Centre format: |r_start - r_end| up to 0.0283 mm and 0.1 % is accepted.
  EXPECT_EQ(error_of("G21 F100\nG2 X200 Y0 I100.01 J0\nM2\n"), "");
  EXPECT_NE(error_of("G21 F100\nG2 X200 Y0 I100.02 J0\nM2\n").find("test.ngc:2: G2: radius to the end differs"),
            std::string::npos);
  // ...both limits: 0.02 mm on a 5 mm radius is 0.4 %.
  EXPECT_NE(error_of("G21 F100\nG2 X10 Y0 I5.01 J0\nM2\n").find("radius to the end differs"), std::string::npos);
  // R format: the chord may exceed the diameter by 0.00127 mm (a semicircle after rounding).
  EXPECT_EQ(error_of("G21 F100\nG2 X10 Y0 R4.9995\nM2\n"), "");
  EXPECT_NE(error_of("G21 F100\nG2 X10 Y0 R4.99\nM2\n").find("test.ngc:2: G2 R4.9900: radius too small"),
            std::string::npos);
  // Inches: 0.00005 in.
  EXPECT_EQ(error_of("G20 F10\nG2 X1 Y0 R0.49996\nM2\n"), "");
  EXPECT_NE(error_of("G20 F10\nG2 X1 Y0 R0.4999\nM2\n").find("radius too small"), std::string::npos);
}

// ---------------------------------------------------------------------------------------------------------------
// Distance modes, units, work offsets

TEST(GcodeModes, IncrementalMoves) {
  const auto m =
      motions(run("G21 F100\n"
                  "G0 X1 Y1 Z1\n"
                  "G91 G1 X1 Y2 Z-1\n"
                  "G1 X-1\n"
                  "G2 X2 Y0 I1 J0\n"  // end (3, 3), centre (2, 3)
                  "G90 G0 X0\n"
                  "M2\n"));
  ASSERT_EQ(m.size(), 5u);
  expect_gcode_xyz(m, 1, 2, 3, 0);
  expect_gcode_xyz(m, 2, 1, 3, 0);
  expect_call(m[3], "ARC_FEED", {3, 3, 2, 3, -1, 0, 0, 0, 0});
  expect_gcode_xyz(m, 4, 0, 3, 0);
}

TEST(GcodeModes, InchProgramsBecomeMillimetresInTheToolPath) {
  const GcodeResult r =
      run("G20\n"
          "F10\n"  // on its own line: an F beside G20 is read first, in the units before it (as LinuxCNC)
          "G0 X1 Y2 Z0.5\n"
          "G1 X2\n"
          "G2 X3 Y3 I0 J1\n"
          "G21 G1 X10\n"  // the feed stays what it physically was (10 in/min)
          "M2\n");
  const auto m = motions(r);
  expect_gcode_xyz(m, 1, 2, 2, 0.5);  // canonical calls keep the program's units
  ASSERT_EQ(r.path.moves.size(), 4u);
  expect_vec(r.path.moves[0].end, v6(25.4, 50.8, 12.7), "G0 in inches");
  expect_vec(r.path.moves[1].end, v6(50.8, 50.8, 12.7), "G1 in inches");
  EXPECT_DOUBLE_EQ(r.path.moves[1].feed_mm_per_min, 254.0);
  const core::Move& arc = r.path.moves[2];
  EXPECT_NEAR(arc.centre_mm.x(), 50.8, 1e-12);
  EXPECT_NEAR(arc.centre_mm.y(), 76.2, 1e-12);
  expect_vec(arc.end, v6(76.2, 76.2, 12.7), "arc in inches");
  expect_vec(r.path.moves[3].end, v6(10, 76.2, 12.7), "after G21");
  EXPECT_DOUBLE_EQ(r.path.moves[3].feed_mm_per_min, 254.0);
}

TEST(GcodeModes, WorkOffsetsG10L2L20G5xG92AreFoldedIntoTheToolPath) {
  const GcodeResult r =
      run("G21 F100\n"
          "G10 L2 P1 X10 Y20 Z30\n"
          "G10 L2 P2 X100\n"
          "G0 X1 Y2 Z3\n"  // G54: (11, 22, 33)
          "G55 G0 X1\n"    // G55 origin (100, 0, 0): (101, 22, 33)
          "G92 X0 Y0\n"    // here is now X0 Y0
          "G0 X5 Y5\n"     // (106, 27, 33)
          "G92.1\n"
          "G10 L20 P2 X0\n"  // G55 moves so that here reads X0: origin X 106
          "G0 Y0\n"          // (106, 0, 33)
          "G59.3 G0 X0 Y0 Z0\n"
          "G54 G0 X0 Y0 Z0\n"  // the G54 origin
          "M2\n");
  const auto t = texts(r);
  const auto m = motions(r);
  ASSERT_EQ(m.size(), 6u);
  expect_gcode_xyz(m, 0, 1, 2, 3);  // canonical calls are in the active system
  expect_gcode_xyz(m, 1, 1, 22, 33);
  expect_gcode_xyz(m, 2, 5, 5, 33);
  expect_gcode_xyz(m, 3, 0, 0, 33);
  EXPECT_NE(std::find(t.begin(), t.end(), "SET_G5X_OFFSET(2, 100.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)"),
            t.end());
  EXPECT_NE(std::find(t.begin(), t.end(), "SET_G92_OFFSET(1.0000, 22.0000, 0.0000, 0.0000, 0.0000, 0.0000)"), t.end());
  EXPECT_NE(std::find(t.begin(), t.end(), "SET_G5X_OFFSET(2, 106.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)"),
            t.end());
  ASSERT_EQ(r.path.moves.size(), 6u);
  expect_vec(r.path.moves[0].end, v6(11, 22, 33), "G54");
  expect_vec(r.path.moves[1].end, v6(101, 22, 33), "G55");
  expect_vec(r.path.moves[2].end, v6(106, 27, 33), "G55 + G92");
  expect_vec(r.path.moves[3].end, v6(106, 0, 33), "G10 L20");
  expect_vec(r.path.moves[4].end, v6(0, 0, 0), "G59.3");
  expect_vec(r.path.moves[5].end, v6(10, 20, 30), "G54 again");
  expect_vec(r.path.initial_position, v6(0, 0, 0), "LinuxCNC starts at zero");
}

TEST(GcodeModes, XyRotationOfG10L2RotatesLinesAndXyArcs) {
  const GcodeResult r =
      run("G21 F100\n"
          "G10 L2 P1 X10 Y20 R90\n"
          "G0 X1 Y0\n"         // rotated 90 degrees about the G54 origin: (10, 21)
          "G3 X0 Y1 I-1 J0\n"  // quarter circle about the origin: ends at (9, 20), centre (10, 20)
          "M2\n");
  ASSERT_EQ(r.path.moves.size(), 2u);
  expect_vec(r.path.moves[0].end, v6(10, 21, 0), "rotated G0");
  expect_vec(r.path.moves[1].end, v6(9, 20, 0), "rotated arc end");
  EXPECT_NEAR(r.path.moves[1].centre_mm.x(), 10, 1e-12);
  EXPECT_NEAR(r.path.moves[1].centre_mm.y(), 20, 1e-12);
  EXPECT_EQ(r.path.moves[1].rotation, 1);
}

TEST(GcodeModes, RotaryAxesAreRadiansInTheToolPath) {
  const GcodeResult r = run("G21 F100\nG1 A90 C-45\nG1 X10 A180\nM2\n");
  ASSERT_EQ(r.path.moves.size(), 2u);
  expect_vec(r.path.moves[0].end, v6(0, 0, 0, std::numbers::pi / 2, 0, -std::numbers::pi / 4), "A C");
  EXPECT_DOUBLE_EQ(r.path.moves[0].feed_mm_per_min, 100.0);  // deg/min: only rotary axes move
}

// ---------------------------------------------------------------------------------------------------------------
// Tools, feeds

TEST(GcodeTools, ToolTableLengthOffsetsAndDiameter) {
  TempDir dir;
  GcodeOptions options;
  options.tool_table = dir.write("tools.tbl", "T1 P1 Z50 D10 ;ten mm end mill\n\nT2 P2 Z-5 D6\n");
  const GcodeResult r = interpret_gcode(dir.write("t.ngc",
                                                  "G21 F100\n"
                                                  "T1 M6\n"
                                                  "G43 H1\n"  // the controlled point moves up 50: Z0 reads -50
                                                  "G0 Z10\n"
                                                  "G1 X5\n"
                                                  "T2 M6 G43\n"  // G43 without H: the tool in the spindle
                                                  "G0 X0\n"
                                                  "G49\n"
                                                  "G0 X1\n"
                                                  "M2\n"),
                                        options);
  const auto t = texts(r);
  EXPECT_NE(std::find(t.begin(), t.end(),
                      "USE_TOOL_LENGTH_OFFSET(0.0000 0.0000 50.0000, 0.0000 0.0000 0.0000, 0.0000 0.0000 0.0000)"),
            t.end());
  EXPECT_NE(std::find(t.begin(), t.end(), "CHANGE_TOOL(2)"), t.end());
  ASSERT_EQ(r.path.moves.size(), 4u);
  const core::Move& up = r.path.moves[0];
  expect_vec(up.start, v6(0, 0, -50), "tip before G0 Z10");
  expect_vec(up.end, v6(0, 0, 10), "G0 Z10");
  EXPECT_EQ(up.tool_number, 1);
  EXPECT_DOUBLE_EQ(up.tool_length_offset_mm, 50.0);
  EXPECT_DOUBLE_EQ(r.path.tool_diameter_mm, 10.0);  // the tool of the first cut
  const core::Move& second = r.path.moves[2];
  expect_vec(second.start, v6(5, 0, 65), "tool 2 is 55 shorter: Z reads 65");
  EXPECT_EQ(second.tool_number, 2);
  EXPECT_DOUBLE_EQ(second.tool_length_offset_mm, -5.0);
  EXPECT_DOUBLE_EQ(r.path.moves[3].start[core::kZ], 60.0);
  EXPECT_DOUBLE_EQ(r.path.moves[3].tool_length_offset_mm, 0.0);
}

TEST(GcodeTools, InchMachineToolTablesAsRs274ReadsThem) {
  TempDir dir;
  GcodeOptions options;
  options.tool_table = dir.write("tools.tbl", "T3 P3 Z1 D0.5\n");
  options.inch_machine = true;
  const GcodeResult r = interpret_gcode(dir.write("t.ngc", "G21 F100\nT3 M6\nG43\nG1 X1\nM2\n"), options);
  const auto t = texts(r);
  EXPECT_NE(std::find(t.begin(), t.end(),
                      "USE_TOOL_LENGTH_OFFSET(0.0000 0.0000 25.4000, 0.0000 0.0000 0.0000, 0.0000 0.0000 0.0000)"),
            t.end());
  EXPECT_DOUBLE_EQ(r.path.tool_diameter_mm, 12.7);
}

TEST(GcodeFeeds, InverseTimeFeedsPerMove) {
  const GcodeResult r =
      run("G21 G17\n"
          "G0 X0 Y0 Z0\n"
          "G93 G1 X10 F2\n"    // 10 mm in 1/2 min: 20 mm/min
          "G1 A90 F1\n"        // rotary only: 90 deg in 1 min
          "G2 X20 Y0 R5 F3\n"  // half circle of R5 in 1/3 min
          "G1 X20 Y0 F5\n"     // no motion: LinuxCNC's floor of 0.1
          "G94 G1 X30 F100\n"
          "M2\n");
  const auto t = body(r);
  const std::vector<std::string> expected_start = {
      "SELECT_PLANE(CANON_PLANE_XY)",
      "USE_LENGTH_UNITS(CANON_UNITS_MM)",
      "STRAIGHT_TRAVERSE(0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
      "COMMENT(\"interpreter: feed mode set to inverse time\")",
      "SET_FEED_MODE(0, 0)",
      "SET_FEED_RATE(20.0000)",
      "STRAIGHT_FEED(10.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
      "SET_FEED_RATE(90.0000)",
      "STRAIGHT_FEED(10.0000, 0.0000, 0.0000, 90.0000, 0.0000, 0.0000)",
      "SET_FEED_RATE(47.1239)",
      // rs274 prints the centre's rounding residue of -3e-16 as -0.0000 too
      "ARC_FEED(20.0000, 0.0000, 15.0000, -0.0000, -1, 0.0000, 90.0000, 0.0000, 0.0000)",
      "SET_FEED_RATE(0.1000)",
  };
  ASSERT_GE(t.size(), expected_start.size());
  for (std::size_t i = 0; i < expected_start.size(); ++i) EXPECT_EQ(t[i], expected_start[i]);
  ASSERT_EQ(r.path.moves.size(), 4u);  // the zero-length G1 is dropped from the ToolPath
  const core::Move& line = r.path.moves[0];
  EXPECT_EQ(line.feed_mode, core::FeedMode::InverseTime);
  EXPECT_DOUBLE_EQ(line.inverse_time_per_min, 2.0);
  EXPECT_DOUBLE_EQ(line.feed_mm_per_min, 20.0);
  EXPECT_DOUBLE_EQ(r.path.moves[1].feed_mm_per_min, 90.0);  // deg/min
  EXPECT_EQ(r.path.moves[2].kind, core::MotionKind::Arc);
  EXPECT_DOUBLE_EQ(r.path.moves[2].inverse_time_per_min, 3.0);
  EXPECT_NEAR(r.path.moves[2].feed_mm_per_min, 15 * std::numbers::pi, 1e-9);
  EXPECT_EQ(r.path.moves[3].feed_mode, core::FeedMode::UnitsPerMinute);
  EXPECT_DOUBLE_EQ(r.path.moves[3].feed_mm_per_min, 100.0);
}

// ---------------------------------------------------------------------------------------------------------------
// Canned cycles

std::vector<std::string> cycle_moves(const std::string& program) {
  std::vector<std::string> out;
  for (const std::string& t : body(run(program)))
    if (t.starts_with("STRAIGHT") || t.starts_with("DWELL")) out.push_back(t);
  return out;
}

std::string T(double x, double y, double z) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "STRAIGHT_TRAVERSE(%.4f, %.4f, %.4f, 0.0000, 0.0000, 0.0000)", x, y, z);
  return buf;
}
std::string F(double x, double y, double z) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "STRAIGHT_FEED(%.4f, %.4f, %.4f, 0.0000, 0.0000, 0.0000)", x, y, z);
  return buf;
}

TEST(GcodeCycles, G81ReturnsToTheInitialLevelWithG98AndToRWithG99) {
  EXPECT_EQ(cycle_moves("G21 F100\nG0 X0 Y0 Z10\nG98 G81 X1 Y2 Z-3 R2\nX5\nG80\nM2\n"),
            (std::vector<std::string>{T(0, 0, 10), T(1, 2, 10), T(1, 2, 2), F(1, 2, -3), T(1, 2, 10), T(5, 2, 10),
                                      T(5, 2, 2), F(5, 2, -3), T(5, 2, 10)}));
  EXPECT_EQ(cycle_moves("G21 F100\nG0 X0 Y0 Z10\nG99 G81 X1 Y2 Z-3 R2\nX5\nG80\nM2\n"),
            (std::vector<std::string>{T(0, 0, 10), T(1, 2, 10), T(1, 2, 2), F(1, 2, -3), T(1, 2, 2), T(5, 2, 2),
                                      F(5, 2, -3), T(5, 2, 2)}));
}

TEST(GcodeCycles, IncrementalCycleWithRepeats) {
  // G91: X steps from hole to hole, R is relative to the initial Z (10), Z to R.
  EXPECT_EQ(cycle_moves("G21 F100\nG0 X0 Y0 Z10\nG91 G99 G81 X10 Y0 Z-5 R-8 L3\nG90 G80\nM2\n"),
            (std::vector<std::string>{T(0, 0, 10), T(10, 0, 10), T(10, 0, 2), F(10, 0, -3), T(10, 0, 2), T(20, 0, 2),
                                      F(20, 0, -3), T(20, 0, 2), T(30, 0, 2), F(30, 0, -3), T(30, 0, 2)}));
}

TEST(GcodeCycles, PeckDwellAndBoringCycles) {
  const std::string start = "G21 F100\nG0 X0 Y0 Z10\nG98 ";
  // G83: out to R after every peck, back in to 0.254 mm above the last depth.
  EXPECT_EQ(cycle_moves(start + "G83 X0 Y0 Z-5 R1 Q2\nG80\nM2\n"),
            (std::vector<std::string>{T(0, 0, 10), T(0, 0, 10), T(0, 0, 1), F(0, 0, -1), T(0, 0, 1), T(0, 0, -0.746),
                                      F(0, 0, -3), T(0, 0, 1), T(0, 0, -2.746), F(0, 0, -5), T(0, 0, 10)}));
  // G73: only backs off 0.254 mm between pecks.
  EXPECT_EQ(cycle_moves(start + "G73 X0 Y0 Z-5 R1 Q2\nG80\nM2\n"),
            (std::vector<std::string>{T(0, 0, 10), T(0, 0, 10), T(0, 0, 1), F(0, 0, -1), T(0, 0, -0.746), F(0, 0, -3),
                                      T(0, 0, -2.746), F(0, 0, -5), T(0, 0, 10)}));
  EXPECT_EQ(
      cycle_moves(start + "G82 X0 Y0 Z-2 R1 P0.5\nG80\nM2\n"),
      (std::vector<std::string>{T(0, 0, 10), T(0, 0, 10), T(0, 0, 1), F(0, 0, -2), "DWELL(0.5000)", T(0, 0, 10)}));
  // G85: feeds out to R, then rapids to the clearance level.
  EXPECT_EQ(cycle_moves(start + "G85 X0 Y0 Z-2 R1\nG80\nM2\n"),
            (std::vector<std::string>{T(0, 0, 10), T(0, 0, 10), T(0, 0, 1), F(0, 0, -2), F(0, 0, 1), T(0, 0, 10)}));
  // G89: dwells, then feeds all the way out.
  EXPECT_EQ(
      cycle_moves(start + "G89 X0 Y0 Z-2 R1 P0.25\nG80\nM2\n"),
      (std::vector<std::string>{T(0, 0, 10), T(0, 0, 10), T(0, 0, 1), F(0, 0, -2), "DWELL(0.2500)", F(0, 0, 10)}));
}

TEST(GcodeCycles, CyclesBecomeRapidAndFeedLinesInTheToolPath) {
  const GcodeResult r = run("G21 F100\nG0 X0 Y0 Z10\nG99 G81 X1 Y2 Z-3 R2\nM2\n");
  ASSERT_EQ(r.path.moves.size(), 5u);  // the first G0 and the cycle's first XY move at Z10, R, feed, retract
  EXPECT_TRUE(r.path.moves[2].rapid);
  EXPECT_FALSE(r.path.moves[3].rapid);
  EXPECT_DOUBLE_EQ(r.path.moves[3].feed_mm_per_min, 100.0);
  expect_vec(r.path.moves[3].end, v6(1, 2, -3), "hole bottom");
  EXPECT_EQ(r.path.moves[3].source_line, 3);
  const auto t = texts(r);
  EXPECT_NE(std::find(t.begin(), t.end(), "SET_MOTION_CONTROL_MODE(CANON_EXACT_PATH)"), t.end());
}

// ---------------------------------------------------------------------------------------------------------------
// Program structure and output format

TEST(GcodeProgram, PreambleNColumnAndZeroLengthMoves) {
  const GcodeResult r =
      run("G0 X0 Y0 Z0\n"
          "N10 G0 X1\n"
          "n0020 G0 X2\n"
          "/N30 G0 X3\n"
          "N1234567 G0 X4\n"
          "M2\n");
  const std::vector<std::string> t = texts(r);
  ASSERT_EQ(t.size(), 6u + 5u + 7u + 2u);
  EXPECT_EQ(t[0], "USE_LENGTH_UNITS(CANON_UNITS_MM)");
  EXPECT_EQ(t[5], "ON_RESET()");
  EXPECT_EQ(r.canon[6].n_word, "N.....");
  EXPECT_EQ(r.canon[7].n_word, "N10");
  EXPECT_EQ(r.canon[8].n_word, "N0020");
  EXPECT_EQ(r.canon[9].n_word, "N30");
  EXPECT_EQ(format_canon_line(8, r.canon[7]),
            "    8 N10    STRAIGHT_TRAVERSE(1.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)");
  EXPECT_EQ(format_canon_line(11, r.canon[10]),
            "   11 N1234567STRAIGHT_TRAVERSE(4.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)");
  EXPECT_EQ(format_canon_line(1, r.canon[0]), "    1 N..... USE_LENGTH_UNITS(CANON_UNITS_MM)");
  EXPECT_EQ(t.back(), "ON_RESET()");
  // The first G0 goes nowhere: it is a canonical call but not a move.
  ASSERT_EQ(r.path.moves.size(), 4u);
  EXPECT_EQ(r.path.moves[0].source_line, 2);
}

TEST(GcodeProgram, BlockDeleteSwitch) {
  const std::string program = "G21\nG0 X1\n/G0 X5\nM2\n";
  EXPECT_EQ(run(program).path.moves.size(), 2u);  // off, as LinuxCNC starts
  GcodeOptions skip;
  skip.block_delete = true;
  EXPECT_EQ(run(program, skip).path.moves.size(), 1u);
}

TEST(GcodeProgram, NoMotionMCodesAreAcceptedSilently) {
  GcodeOptions options;
  options.no_motion_mcodes = {428, 429};
  const GcodeResult r = run("M428 ;kinematics switch\nG0 X1\nM429\nM2\n", options);
  EXPECT_EQ(motions(r).size(), 1u);
  EXPECT_EQ(body(r).size(), 1u + 7u);  // the move, then M2's resets
}

TEST(GcodeProgram, PercentFramingEndsTheProgram) {
  const GcodeResult r = run("%\nG21 G0 X1\n%\nthis is not G-code\n");
  const auto t = texts(r);
  ASSERT_GE(t.size(), 3u);
  EXPECT_EQ(t[t.size() - 3], "FINISH()");
  EXPECT_EQ(r.path.moves.size(), 1u);
}

TEST(GcodeProgram, CommentsMessagesAndTheLastCommentOfALine) {
  const auto t = body(run("(first) G21 (second)\n(MSG, hello )\n;not a canonical call\nM2\n"));
  ASSERT_GE(t.size(), 3u);
  EXPECT_EQ(t[0], "COMMENT(\"second\")");
  EXPECT_EQ(t[1], "USE_LENGTH_UNITS(CANON_UNITS_MM)");
  EXPECT_EQ(t[2], "MESSAGE(\" hello \")");
}

}  // namespace
}  // namespace vmsim::program::gcode_test
