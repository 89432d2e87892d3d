// Sinumerik 840D reader on small hand-written programs, one construct each. The expected canonical calls are worked
// out by hand from Siemens' SINUMERIK 840D sl documentation (NC programming: Fundamentals and Work preparation; the
// cycles' programming manual): what each statement means, the arc conventions (I J K relative to the start, CR=+r
// for arcs up to 180 degrees, CR=-r beyond, TURN= full turns), frames (TRANS/ROT replace, ATRANS/AROT add in the
// frame already defined, ROT order Z Y' X''), and the cycles' documented sequences. The calls are written in
// LinuxCNC's canonical vocabulary (ARC_FEED's plane axis order and rotation sign as LinuxCNC's canon).
#include "core/error.hpp"
#include "program/program.hpp"
#include "program/sinumerik.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace vmsim::program {
namespace {

namespace fs = std::filesystem;

SinumerikResult run(const std::string& text, const SinumerikOptions& options = {}) {
  return interpret_sinumerik_text(text, "test.mpf", options);
}

// The canonical calls' texts (no numbering, no N column).
std::vector<std::string> calls(const SinumerikResult& r, bool comments = false) {
  std::vector<std::string> out;
  for (const CanonCall& c : r.canon)
    if (comments || (c.text.rfind("COMMENT", 0) != 0 && c.text.rfind("MESSAGE", 0) != 0)) out.push_back(c.text);
  return out;
}

// Only the motion calls.
std::vector<std::string> moves(const SinumerikResult& r) {
  std::vector<std::string> out;
  for (const CanonCall& c : r.canon)
    if (c.text.rfind("STRAIGHT_", 0) == 0 || c.text.rfind("ARC_FEED", 0) == 0) out.push_back(c.text);
  return out;
}

std::string sinumerik_error_of(const std::string& text, const SinumerikOptions& options = {}) {
  try {
    run(text, options);
  } catch (const core::Error& e) {
    return e.what();
  }
  return "";
}

TEST(Sinumerik, CommentsVariablesRParametersAndExpressions) {
  const SinumerikResult r =
      run("N10 ;Start of Program\n"
          "N20 DEF REAL _A, _B=2\n"
          "N30 DEF INT _N\n"
          "N40 R1=3 _A=R1*_B+1 _N=7/2\n"           // INT assignment rounds: 3.5 -> 4
          "N50 G90 G17 G0 X=_A Y=R1-1 Z=POT(2)\n"  // 7, 2, 4
          "N60 G0 X=2+3*4 Y=(2+3)*4 Z=_N\n"        // 14, 20, 4
          "N70 G0 X=SIN(30)*10 Y=ATAN2(1,1) Z=SQRT(16)+ABS(-1)\n"
          "N80 G0 X=TRUNC(-2.7) Y=ROUND(2.5) Z=7 MOD 4\n");
  EXPECT_EQ(moves(r), (std::vector<std::string>{
                          "STRAIGHT_TRAVERSE(7.0000, 2.0000, 4.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(14.0000, 20.0000, 4.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(5.0000, 45.0000, 5.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(-2.0000, 3.0000, 3.0000, 0.0000, 0.0000, 0.0000)",
                      }));
  EXPECT_EQ(r.canon.front().text, "COMMENT(\"Start of Program\")");
  EXPECT_EQ(r.canon.front().n_word, "N10");
  EXPECT_EQ(r.canon.front().source_line, 1);
}

TEST(Sinumerik, ComparisonsBindLoosestAndCompareExactly) {
  // 840D priority: comparisons after AND/OR, so (R1==1) AND (R2==2) needs its brackets; 1 == 1.00001 is false
  // (the 840D compares REAL values exactly, not with LinuxCNC's 1e-4).
  const SinumerikResult r =
      run("R1=1 R2=2\n"
          "G0 X=(R1==1) AND (R2==2) Y=R1==1.00001 Z=1+1==2\n"
          "G0 X=R1<>1 Y=R1<=1 Z=NOT R1\n");
  EXPECT_EQ(moves(r), (std::vector<std::string>{
                          "STRAIGHT_TRAVERSE(1.0000, 0.0000, 1.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(0.0000, 1.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                      }));
}

TEST(Sinumerik, LabelsGotoAndIfElseWhile) {
  const SinumerikResult r =
      run("N10 DEF INT _N=0\n"
          "N20 G1 F100\n"
          "LOOP: _N=_N+1\n"
          "N40 X=_N\n"
          "N50 IF _N<3 GOTOB LOOP\n"
          "N60 GOTOF SKIP\n"
          "N70 X99\n"
          "SKIP:\n"
          "N90 IF _N==3\n"
          "N100 Y1\n"
          "N110 ELSE\n"
          "N120 Y2\n"
          "N130 ENDIF\n"
          "N140 WHILE _N>1\n"
          "N150 _N=_N-1\n"
          "N160 Z=_N\n"
          "N170 ENDWHILE\n"
          "N180 GOTOF N200\n"
          "N190 X98\n"
          "N200 M30\n"
          "N210 X97\n");
  EXPECT_EQ(moves(r), (std::vector<std::string>{
                          "STRAIGHT_FEED(1.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_FEED(2.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_FEED(3.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_FEED(3.0000, 1.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_FEED(3.0000, 1.0000, 2.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_FEED(3.0000, 1.0000, 1.0000, 0.0000, 0.0000, 0.0000)",
                      }));
  EXPECT_EQ(r.canon.back().text, "PROGRAM_END()");
}

TEST(Sinumerik, ArcsWithCentreRadiusAndTurns) {
  const SinumerikResult r =
      run("G17 G90 G0 X10 Y0 Z0\n"
          "G3 X0 Y10 I-10 J0 F500\n"  // centre (0,0), counter-clockwise
          "G0 X10 Y0\n"
          "G3 X0 Y10 CR=10\n"  // up to 180 deg: the same arc
          "G0 X10 Y0\n"
          "G3 X0 Y10 CR=-10\n"  // over 180 deg: centre (10,10)
          "G0 X10 Y0\n"
          "G2 X0 Y10 CR=10\n"  // clockwise up to 180 deg: centre (10,10)
          "G0 X10 Y0\n"
          "G2 X0 Y10 I=AC(0) J=AC(0)\n"  // absolute centre, clockwise the long way
          "G0 X10 Y0 Z0\n"
          "G3 X10 Y0 Z-2 I-10 J0 TURN=2\n"  // helix: 3 full turns down to Z-2
          "G18 G0 X10 Y0 Z0\n"
          "G3 X0 Z10 I-10 K0\n");  // ZX plane: (first, second) = (z, x)
  const std::vector<std::string> arcs = [&] {
    std::vector<std::string> a;
    for (const std::string& m : moves(r))
      if (m.rfind("ARC_FEED", 0) == 0) a.push_back(m);
    return a;
  }();
  EXPECT_EQ(arcs, (std::vector<std::string>{
                      "ARC_FEED(0.0000, 10.0000, 0.0000, 0.0000, 1, 0.0000, 0.0000, 0.0000, 0.0000)",
                      "ARC_FEED(0.0000, 10.0000, 0.0000, 0.0000, 1, 0.0000, 0.0000, 0.0000, 0.0000)",
                      "ARC_FEED(0.0000, 10.0000, 10.0000, 10.0000, 1, 0.0000, 0.0000, 0.0000, 0.0000)",
                      "ARC_FEED(0.0000, 10.0000, 10.0000, 10.0000, -1, 0.0000, 0.0000, 0.0000, 0.0000)",
                      "ARC_FEED(0.0000, 10.0000, 0.0000, 0.0000, -1, 0.0000, 0.0000, 0.0000, 0.0000)",
                      "ARC_FEED(10.0000, 0.0000, 0.0000, 0.0000, 3, -2.0000, 0.0000, 0.0000, 0.0000)",
                      "ARC_FEED(10.0000, 0.0000, 0.0000, 0.0000, 1, 0.0000, 0.0000, 0.0000, 0.0000)",
                  }));
  EXPECT_EQ(r.stats.arc_blocks, 7);
  // The ToolPath's last arc: ZX plane, centre (z, x) = (0, 0), end (0, 0, 10).
  const core::Move& last = r.path.moves.back();
  EXPECT_EQ(last.kind, core::MotionKind::Arc);
  EXPECT_EQ(last.plane, core::ArcPlane::ZX);
  EXPECT_NEAR(last.end[2], 10.0, 1e-12);
  EXPECT_EQ(last.rotation, 1);
  EXPECT_DOUBLE_EQ(last.feed_mm_per_min, 500.0);
  // An end point off the circle by more than 0.01 mm is refused (840D MD21000 default).
  EXPECT_NE(
      sinumerik_error_of("G0 X10 Y0\nG3 X0 Y10.02 I-10 J0 F100\n").find("test.mpf:2: the end point is 0.0200 mm off"),
      std::string::npos);
}

TEST(Sinumerik, AbsoluteAndIncrementalWords) {
  const SinumerikResult r =
      run("G90 G0 X10\n"
          "X=IC(5)\n"  // 15
          "G91 X5\n"   // 20
          "X=AC(1)\n"  // 1
          "G90 B30 C=IC(10)\n");
  EXPECT_EQ(moves(r), (std::vector<std::string>{
                          "STRAIGHT_TRAVERSE(10.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(15.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(20.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(1.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(1.0000, 0.0000, 0.0000, 0.0000, 30.0000, 10.0000)",
                      }));
  EXPECT_NEAR(r.path.moves.back().end[core::kB], 30.0 * M_PI / 180, 1e-15);
}

TEST(Sinumerik, FramesTransRotAndTheirAdditiveForms) {
  const SinumerikResult r =
      run("TRANS X10\n"
          "G0 X0 Y0 Z0\n"  // (10, 0, 0)
          "AROT Z90\n"
          "G0 X1 Y0\n"     // (10, 1, 0): x of the turned frame is +Y
          "ATRANS X5\n"    // 5 along the turned x: origin (10, 5, 0)
          "G0 X0 Y0\n"     // (10, 5, 0)
          "ROT Y90\n"      // replaces everything: a turn about Y alone
          "G0 X0 Y0 Z1\n"  // Ry(90) (0,0,1) = (1, 0, 0)
          "ROT X90 Y90\n"  // order Z, Y', X'': Ry(90) Rx(90)
          "G0 X0 Y1 Z0\n"  // Ry(90) Rx(90) (0,1,0) = Ry(90) (0,0,1) = (1, 0, 0)
          "TRANS\n"
          "SUPA G0 X3\n"  // no frame: (3, 0, 0) before and after
          "G0 X0 Y0 Z0\n");
  EXPECT_EQ(moves(r), (std::vector<std::string>{
                          "STRAIGHT_TRAVERSE(10.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(10.0000, 1.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(10.0000, 5.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(1.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(1.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(3.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                      }));
  EXPECT_EQ(r.stats.frame_statements, 6);
}

TEST(Sinumerik, ArcInATurnedFrameStaysAnArcOrBecomesChords) {
  // AROT Y90: the frame's XY plane is the workpiece's YZ plane seen from +X (frame z = +X); a G3 there is
  // counter-clockwise about +X: ARC_FEED in (y, z) with rotation +1.
  const SinumerikResult r =
      run("AROT Y90\n"
          "G0 X0 Y0 Z5\n"  // workpiece (5, 0, 0)
          "G0 X10 Y0\n"    // Ry(90) (10,0,5) = (5, 0, -10)
          "G3 X0 Y10 I-10 J0 F100\n");
  const std::vector<std::string> m = moves(r);
  ASSERT_EQ(m.size(), 3u);
  EXPECT_EQ(m[1], "STRAIGHT_TRAVERSE(5.0000, 0.0000, -10.0000, 0.0000, 0.0000, 0.0000)");
  // end Ry(90) (0,10,5) = (5, 10, 0); centre (5, 0, 0): (y, z) = (0, 0)
  EXPECT_EQ(m[2], "ARC_FEED(10.0000, 0.0000, 0.0000, 0.0000, 1, 5.0000, 0.0000, 0.0000, 0.0000)");
  EXPECT_EQ(r.path.moves.back().plane, core::ArcPlane::YZ);

  // A frame turned by 45 deg about two axes: the plane has no name in the workpiece frame; chords within 1 um, every
  // chord end on the programmed circle (radius 10 about the frame's centre).
  const SinumerikResult c =
      run("AROT X90\nAROT Y-45\n"
          "G0 X10 Y0 Z0\n"
          "G3 X0 Y10 I-10 J0 F100\n");
  EXPECT_EQ(c.stats.chorded_arcs, 1);
  EXPECT_EQ(c.stats.arc_blocks, 1);
  ASSERT_GT(c.path.moves.size(), 20u);
  for (std::size_t i = 1; i < c.path.moves.size(); ++i) {
    EXPECT_NEAR(c.path.moves[i].end.head<3>().norm(), 10.0, 1e-9);
    // the chord's middle is within the tolerance of the circle
    const Eigen::Vector3d mid = 0.5 * (c.path.moves[i].start.head<3>() + c.path.moves[i].end.head<3>());
    EXPECT_LE(10.0 - mid.norm(), 1e-3 + 1e-12);
  }
}

// A B/C table machine whose tool axis in the workpiece frame is (sin B cos C, sin B sin C, cos B), with the tip moved
// by a fixed offset between joint and tool-centre-point coordinates, so that the transitions can be seen.
class FakeMachine final : public MachineTransform {
 public:
  Eigen::Vector3d tip_of_joint(const core::Vec6& j) const override { return j.head<3>() + Eigen::Vector3d(100, 0, 0); }
  core::Vec6 joint_of_tip(const core::Vec6& t) const override {
    core::Vec6 j = t;
    j.head<3>() -= Eigen::Vector3d(100, 0, 0);
    return j;
  }
  Eigen::Vector3d rotary_for_tool_axis(const Eigen::Vector3d& a, const core::Vec6&) const override {
    return Eigen::Vector3d(0, std::acos(a.z()), std::atan2(a.y(), a.x()));
  }
};

TEST(Sinumerik, TraoriMovesAreToolCentrePointMovesInTheFrame) {
  const char* text =
      "G0 X1 Y2 Z3 B90 C0\n"  // joint move
      "TRAORI\n"
      "AROT Y90\n"
      "G1 X0 Y0 Z5 F100\n"  // tip at Ry(90) (0,0,5) = (5, 0, 0), rotary axes as they are
      "TRANS X0 Y0 Z0\n"
      "TRAFOOF\n"
      "SUPA G0 Z610\n";  // machine position
  const SinumerikResult r = run(text);
  ASSERT_EQ(r.path.moves.size(), 3u);
  EXPECT_FALSE(r.path.moves[0].tcp);
  EXPECT_TRUE(r.path.moves[1].tcp);
  EXPECT_FALSE(r.path.moves[2].tcp);
  EXPECT_NEAR((r.path.moves[1].end.head<3>() - Eigen::Vector3d(5, 0, 0)).norm(), 0, 1e-12);
  EXPECT_NEAR(r.path.moves[1].end[core::kB], M_PI / 2, 1e-15);
  EXPECT_EQ(r.stats.tcp_moves, 1);
  // Without a machine the reader takes tip = axes at the switch; with one, the switch asks it where the tip is.
  EXPECT_NEAR((r.path.moves[1].start.head<3>() - Eigen::Vector3d(1, 2, 3)).norm(), 0, 1e-12);
  FakeMachine fake;
  SinumerikOptions o;
  o.machine = &fake;
  const SinumerikResult m = run(text, o);
  EXPECT_NEAR((m.path.moves[1].start.head<3>() - Eigen::Vector3d(101, 2, 3)).norm(), 0, 1e-12);
  // After TRAFOOF the joint coordinates come back: the tip (5,0,0) is joint (-95,0,0); SUPA Z610 keeps X and Y.
  EXPECT_NEAR((m.path.moves[2].start.head<3>() - Eigen::Vector3d(-95, 0, 0)).norm(), 0, 1e-12);
  EXPECT_NEAR((m.path.moves[2].end.head<3>() - Eigen::Vector3d(-95, 0, 610)).norm(), 0, 1e-12);
  // SUPA under TRAORI is refused.
  EXPECT_NE(sinumerik_error_of("TRAORI\nSUPA G0 Z10\n").find("test.mpf:2: SUPA / G53 under TRAORI"), std::string::npos);
}

TEST(Sinumerik, Cycle800SwivelsThroughTheMachine) {
  const char* text =
      "G0 X0 Y0 Z50\n"
      "CYCLE800(0,\"TABLE\",100000,57,0,0,0,0,90,0,0,0,0,-1,100,1)\n"  // axis by axis X Y Z: a turn of 90 about Y
      "G0 X0 Y0 Z5\n"                                                  // the swivelled plane: tip Ry(90)(0,0,5)
      "CYCLE800()\n";
  EXPECT_NE(
      sinumerik_error_of(text).find("test.mpf:2: CYCLE800 turns the rotary axes through the machine's kinematics"),
      std::string::npos);
  FakeMachine fake;
  SinumerikOptions o;
  o.machine = &fake;
  const SinumerikResult r = run(text, o);
  const std::vector<std::string> m = moves(r);
  ASSERT_EQ(m.size(), 3u);
  EXPECT_EQ(m[1], "STRAIGHT_TRAVERSE(0.0000, 0.0000, 50.0000, 0.0000, 90.0000, 0.0000)");  // rotary axes only
  EXPECT_EQ(m[2], "STRAIGHT_TRAVERSE(5.0000, 0.0000, 0.0000, 0.0000, 90.0000, 0.0000)");
  EXPECT_TRUE(r.path.moves.back().tcp);
  // The retraction _FR names positions the program does not give: refused.
  EXPECT_NE(
      sinumerik_error_of("CYCLE800(1,\"TABLE\",100000,57,0,0,0,0,90,0,0,0,0,-1,100,1)\n", o).find("retraction _FR=1"),
      std::string::npos);
}

TEST(Sinumerik, ToolCallsSpindleCoolantAndEnd) {
  const SinumerikResult r =
      run("T=\"MILL_A\"\nM6\nS1000 M3 M8\nT=\"DRILL_B\" M6\nT=\"MILL_A\"\nM6 D1\nM5 M9\nT0 M6\nM30\nG0 X99\n");
  EXPECT_EQ(r.tools, (std::vector<std::string>{"MILL_A", "DRILL_B"}));
  EXPECT_EQ(calls(r),
            (std::vector<std::string>{"SELECT_TOOL(1)", "CHANGE_TOOL(1)", "SET_SPINDLE_SPEED(0, 1000.0000)",
                                      "START_SPINDLE_CLOCKWISE(0)", "FLOOD_ON()", "SELECT_TOOL(2)", "CHANGE_TOOL(2)",
                                      "SELECT_TOOL(1)", "CHANGE_TOOL(1)", "STOP_SPINDLE_TURNING(0)", "MIST_OFF()",
                                      "FLOOD_OFF()", "SELECT_TOOL(0)", "CHANGE_TOOL(0)", "PROGRAM_END()"}));
  EXPECT_EQ(r.stats.tool_changes, 4);
}

TEST(Sinumerik, Cycle832SetsTheContourToleranceAndMode) {
  const SinumerikResult r =
      run("DEF REAL _camtolerance\n_camtolerance=.02\n"
          "CYCLE832(_camtolerance,1,1)\n"
          "G1 X1 F100\n"
          "CYCLE832(0.05,3,1)\n"
          "G1 X2\n"
          "CYCLE832()\n"
          "G1 X3\n");
  const std::vector<std::string> c = calls(r);
  EXPECT_EQ(c, (std::vector<std::string>{
                   "SET_MOTION_CONTROL_MODE(CANON_CONTINUOUS, 0.020000)", "SET_NAIVECAM_TOLERANCE(0.0200)",
                   "SET_FEED_RATE(100.0000)", "STRAIGHT_FEED(1.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                   "SET_MOTION_CONTROL_MODE(CANON_CONTINUOUS, 0.050000)", "SET_NAIVECAM_TOLERANCE(0.0500)",
                   "STRAIGHT_FEED(2.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)",
                   "SET_MOTION_CONTROL_MODE(CANON_CONTINUOUS, 0.000000)",
                   "STRAIGHT_FEED(3.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)"}));
  ASSERT_EQ(r.interp_settings.size(), 3u);
  EXPECT_EQ(r.interp_settings[0].what, "CYCLE832 finishing");
  EXPECT_EQ(r.interp_settings[1].what, "CYCLE832 roughing");
  EXPECT_DOUBLE_EQ(*r.interp_settings[1].tolerance_mm, 0.05);
  EXPECT_EQ(r.interp_settings[2].what, "CYCLE832 deselect (G64)");
  ASSERT_TRUE(r.contour_tolerance_mm.has_value());
  EXPECT_DOUBLE_EQ(*r.contour_tolerance_mm, 0.02);  // the smallest in force for a feed move
}

TEST(Sinumerik, DrillingCyclesMakeTheirDocumentedMotion) {
  // CYCLE81(RTP, RFP, SDIS, DP): G0 to RFP + SDIS, G1 to DP, G0 to RTP. As a modal call after each positioning.
  const SinumerikResult r =
      run("G0 X10 Y20 Z50 F100\n"
          "CYCLE81(10,0,2,-5)\n"
          "MCALL CYCLE81(10,0,2,,5)\n"  // DPR = 5 below the reference plane
          "X30\n"
          "MCALL\n"
          "X40\n");
  EXPECT_EQ(moves(r), (std::vector<std::string>{
                          "STRAIGHT_TRAVERSE(10.0000, 20.0000, 50.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(10.0000, 20.0000, 2.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_FEED(10.0000, 20.0000, -5.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(10.0000, 20.0000, 10.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(30.0000, 20.0000, 10.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(30.0000, 20.0000, 2.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_FEED(30.0000, 20.0000, -5.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(30.0000, 20.0000, 10.0000, 0.0000, 0.0000, 0.0000)",
                          "STRAIGHT_TRAVERSE(40.0000, 20.0000, 10.0000, 0.0000, 0.0000, 0.0000)",
                      }));
  EXPECT_EQ(r.stats.cycle_calls, 2);

  // CYCLE83 chip removal (VARI=1): first depth -4, degression 1 (steps 4, 3, 2, 1), back to the safety plane after
  // each step and down again with G0 to 0.6 mm above the last depth (the automatic anticipation distance up to
  // 30 mm of depth).
  auto z_of = [](const std::vector<std::string>& ms) {
    std::vector<std::string> z;
    for (const std::string& m : ms) {
      const std::size_t a = m.find(", ", m.find(", ") + 2) + 2;
      z.push_back(m.substr(0, m.find('(')) + " " + m.substr(a, m.find(',', a) - a));
    }
    return z;
  };
  const SinumerikResult d = run("G0 X0 Y0 Z20 F100\nCYCLE83(10,0,1,-10,,-4,,1,0,0,1,1)\n");
  std::vector<std::string> ms = moves(d);
  ms.erase(ms.begin());
  EXPECT_EQ(z_of(ms), (std::vector<std::string>{
                          "STRAIGHT_TRAVERSE 1.0000", "STRAIGHT_FEED -4.0000", "STRAIGHT_TRAVERSE 1.0000",
                          "STRAIGHT_TRAVERSE -3.4000", "STRAIGHT_FEED -7.0000", "STRAIGHT_TRAVERSE 1.0000",
                          "STRAIGHT_TRAVERSE -6.4000", "STRAIGHT_FEED -9.0000", "STRAIGHT_TRAVERSE 1.0000",
                          "STRAIGHT_TRAVERSE -8.4000", "STRAIGHT_FEED -10.0000", "STRAIGHT_TRAVERSE 10.0000"}));
  // Chip breaking (VARI=0): back off 1 mm after each step.
  const SinumerikResult b = run("G0 X0 Y0 Z20 F100\nCYCLE83(10,0,1,-10,,-4,,1,0,0,1,0)\n");
  ms = moves(b);
  ms.erase(ms.begin());
  EXPECT_EQ(z_of(ms), (std::vector<std::string>{
                          "STRAIGHT_TRAVERSE 1.0000", "STRAIGHT_FEED -4.0000", "STRAIGHT_TRAVERSE -3.0000",
                          "STRAIGHT_FEED -7.0000", "STRAIGHT_TRAVERSE -6.0000", "STRAIGHT_FEED -9.0000",
                          "STRAIGHT_TRAVERSE -8.0000", "STRAIGHT_FEED -10.0000", "STRAIGHT_TRAVERSE 10.0000"}));
}

TEST(Sinumerik, UnknownStatementsAreErrorsNamingFileLineAndWord) {
  EXPECT_EQ(sinumerik_error_of("G0 X0\nN20 FOO X1\n"), "test.mpf:2: unknown word \"FOO\"");
  EXPECT_NE(sinumerik_error_of("G0 X0\nM50\n").find("test.mpf:2: M50: the machine maker's M function"),
            std::string::npos);
  EXPECT_NE(sinumerik_error_of("_X=1\n").find("test.mpf:1: _X=...: variable _X is not defined"), std::string::npos);
  EXPECT_NE(sinumerik_error_of("GOTOF NOWHERE\n").find("test.mpf:1: jump target NOWHERE not found"), std::string::npos);
  EXPECT_NE(sinumerik_error_of("G41 X1\n").find("test.mpf:1: G41: cutter radius compensation"), std::string::npos);
  EXPECT_NE(sinumerik_error_of("L100\n").find("test.mpf:1: unknown word \"L100\""), std::string::npos);
  EXPECT_NE(sinumerik_error_of("MYSUB(1)\n").find("test.mpf:1: MYSUB(): subprogram or cycle not supported"),
            std::string::npos);
  EXPECT_NE(sinumerik_error_of("G1 X1\n").find("test.mpf:1: a feed move (G1, G2, G3) without a feed"),
            std::string::npos);
  EXPECT_NE(sinumerik_error_of("IF R1==1\nG0 X1\n").find("test.mpf:1: IF without ENDIF"), std::string::npos);
  EXPECT_NE(sinumerik_error_of("G0 X=SIN(\n").find("test.mpf:1:"), std::string::npos);
  // A line that cannot be read is an error only when it runs (a jump over it is fine, as on the 840D).
  EXPECT_EQ(sinumerik_error_of("GOTOF END\nFOO\nEND: M30\n"), "");

  // Lenient: statements known to have no motion become warnings naming file and line; unknown words stay errors.
  SinumerikOptions lenient;
  lenient.lenient = true;
  const SinumerikResult r = run("G0 X0\nM50\nM29 M51\nH2\nWAITM(1,1,2)\nG0 X1\n", lenient);
  ASSERT_EQ(r.warnings.size(), 5u);
  EXPECT_EQ(r.warnings[0].rfind("test.mpf:2: M50", 0), 0u);
  EXPECT_EQ(r.warnings[1].rfind("test.mpf:3: M29", 0), 0u);
  EXPECT_EQ(r.warnings[2].rfind("test.mpf:3: M51", 0), 0u);
  EXPECT_EQ(r.warnings[3].rfind("test.mpf:4: H2", 0), 0u);
  EXPECT_EQ(r.warnings[4].rfind("test.mpf:5: WAITM()", 0), 0u);
  EXPECT_EQ(moves(r).size(), 2u);
  EXPECT_EQ(sinumerik_error_of("FOO\n", lenient), "test.mpf:1: unknown word \"FOO\"");
  // The machine's own M functions, named: accepted silently.
  SinumerikOptions named;
  named.no_motion_mcodes = {50};
  EXPECT_TRUE(run("M50\n", named).warnings.empty());
}

TEST(Sinumerik, DialectByExtensionContentOrName) {
  EXPECT_TRUE(looks_like_sinumerik_program("N10 ;x\nN20 DEF REAL _A\n"));
  EXPECT_TRUE(looks_like_sinumerik_program("G0 X0\nCYCLE832(0.01,1,1)\n"));
  EXPECT_TRUE(looks_like_sinumerik_program("T=\"D10\" M6\n"));
  // RS274/NGC: comments in brackets (even naming MSG), ';' comments, #parameters, O-words.
  EXPECT_FALSE(looks_like_sinumerik_program("(MSG, DEF TRAORI)\nG0 X1 ; CYCLE81(\n#1=2\no100 sub\n"));
  EXPECT_FALSE(looks_like_sinumerik_program("G90G20M03S2000\nG1X1Y2\n"));

  const fs::path dir = fs::temp_directory_path() / "vmsim_sinumerik_test_dialect";
  fs::create_directories(dir);
  const std::string sin = "N10 DEF REAL _Z\nN20 _Z=5\nN30 G0 X1 Y2 Z=_Z\nN40 M30\n";
  std::ofstream(dir / "a.mpf") << sin;
  std::ofstream(dir / "b.txt") << sin;
  std::ofstream(dir / "c.ngc") << sin;
  std::ofstream(dir / "d.txt") << "G0 X1 Y2 Z5\nM2\n";
  EXPECT_EQ(program_dialect(dir / "a.mpf"), Dialect::Sinumerik);
  EXPECT_EQ(program_dialect(dir / "b.txt"), Dialect::Sinumerik);
  EXPECT_EQ(program_dialect(dir / "c.ngc"), Dialect::Sinumerik);
  EXPECT_EQ(program_dialect(dir / "d.txt"), Dialect::Rs274ngc);
  EXPECT_EQ(program_dialect(dir / "d.txt", Dialect::Sinumerik), Dialect::Sinumerik);
  const core::ToolPath a = read_program(dir / "a.mpf");
  ASSERT_EQ(a.moves.size(), 1u);
  EXPECT_NEAR((a.moves[0].end.head<3>() - Eigen::Vector3d(1, 2, 5)).norm(), 0, 1e-12);
  EXPECT_EQ(a.moves[0].source_line, 3);
  // The same statements read as RS274/NGC fail ("DEF" means nothing there): the dialect matters.
  ProgramOptions ngc;
  ngc.dialect = Dialect::Rs274ngc;
  EXPECT_THROW(read_program(dir / "a.mpf", ngc), core::Error);
  EXPECT_THROW(parse_dialect("fanuc"), core::Error);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace vmsim::program
