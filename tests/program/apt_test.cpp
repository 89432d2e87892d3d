// APT CL reader. References: ISO 4343 (record forms, RAPID applies to the next motion only, CIRCLE/ motion
// counter-clockwise about its axis) and LinuxCNC's ARC_FEED conventions for the ToolPath arcs (plane axis order
// XY / ZX / YZ, rotation > 0 counter-clockwise seen from the plane normal's positive side). Each program is
// small enough to check by hand; the samples mimic what CATIA, NX and Autodesk's ISO 4343 post write.
#include "program/apt.hpp"
#include "core/error.hpp"
#include "program/program.hpp"

#include <gtest/gtest.h>

#include "tests/test_paths.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

namespace vmsim::program {
namespace {

namespace fs = std::filesystem;

// Writes `text` to a fresh file named after the running test, so parallel test processes never share one.
fs::path write_cl(const std::string& text, const std::string& name = "prog.apt") {
  return vmsim::test::write_test_file("vmsim_apt_test", name, text);
}

// The message of the core::Error that reading `text` throws ("" when it does not throw).
std::string apt_error_of(const std::string& text) {
  const fs::path p = write_cl(text);
  try {
    read_apt(p);
  } catch (const core::Error& e) {
    return e.what();
  }
  return "";
}

void expect_xyz(const core::Vec6& v, double x, double y, double z) {
  EXPECT_NEAR(v[core::kX], x, 1e-9);
  EXPECT_NEAR(v[core::kY], y, 1e-9);
  EXPECT_NEAR(v[core::kZ], z, 1e-9);
  EXPECT_EQ(v[core::kA], 0.0);
  EXPECT_EQ(v[core::kB], 0.0);
  EXPECT_EQ(v[core::kC], 0.0);
}

TEST(Apt, ThreeAxisGotosFeedsAndRapid) {
  const fs::path p = write_cl(
      "PARTNO TEST PART\n"        // 1
      "UNITS/MM\n"                // 2
      "FROM/0,0,100\n"            // 3
      "RAPID\n"                   // 4
      "GOTO/10,20,50\n"           // 5: rapid
      "FEDRAT/MMPM,500\n"         // 6
      "GOTO/10,20,-1\n"           // 7: feed 500
      "FEDRAT/ 1200.0000,MMPM\n"  // 8
      "GOTO/ 30.0, 20.0, -1.\n"   // 9: feed 1200
      "RAPID\n"                   // 10
      "GOTO/30,20,50\n"           // 11: rapid
      "GOTO/0,0,50\n"             // 12: feed again (RAPID was for one motion)
      "END\n"
      "FINI\n");
  const core::ToolPath tp = read_apt(p);
  EXPECT_EQ(tp.source_path, p.string());
  expect_xyz(tp.initial_position, 0, 0, 100);
  ASSERT_EQ(tp.moves.size(), 5u);
  const int lines[] = {5, 7, 9, 11, 12};
  const bool rapid[] = {true, false, false, true, false};
  const double feed[] = {0, 500, 1200, 0, 1200};
  for (std::size_t i = 0; i < 5; ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(tp.moves[i].source_line, lines[i]);
    EXPECT_EQ(tp.moves[i].rapid, rapid[i]);
    EXPECT_EQ(tp.moves[i].kind, core::MotionKind::Line);
    EXPECT_EQ(tp.moves[i].feed_mode, core::FeedMode::UnitsPerMinute);
    EXPECT_DOUBLE_EQ(tp.moves[i].feed_mm_per_min, feed[i]);
    // A 3-axis file gives no tool axis.
    EXPECT_FALSE(tp.moves[i].tool_axis_start.has_value());
    EXPECT_FALSE(tp.moves[i].tool_axis_end.has_value());
    // Each move starts where the previous one ended.
    const core::Vec6 prev_end = i == 0 ? tp.initial_position : tp.moves[i - 1].end;
    EXPECT_EQ(tp.moves[i].start, prev_end);
  }
  expect_xyz(tp.moves[0].end, 10, 20, 50);
  expect_xyz(tp.moves[2].end, 30, 20, -1);
  expect_xyz(tp.moves[4].end, 0, 0, 50);
}

TEST(Apt, FirstGotoIsTheInitialPositionWithoutFrom) {
  const core::ToolPath tp = read_apt(write_cl("RAPID\nGOTO/5,6,7\nFEDRAT/100\nGOTO/5,6,0\n"));
  expect_xyz(tp.initial_position, 5, 6, 7);  // no move from the origin
  ASSERT_EQ(tp.moves.size(), 1u);
  expect_xyz(tp.moves[0].start, 5, 6, 7);
  expect_xyz(tp.moves[0].end, 5, 6, 0);
  EXPECT_FALSE(tp.moves[0].rapid);  // the RAPID was spent on the first GOTO
}

TEST(Apt, FiveAxisToolAxesAreNormalisedAndCarriedOnEveryMove) {
  const core::ToolPath tp =
      read_apt(write_cl("MULTAX/ON\n"
                        "FEDRAT/1000\n"
                        "GOTO/0,0,10,0,0,2\n"       // axis (0,0,1) after normalising
                        "GOTO/10,0,10,0.6,0,0.8\n"  // tilt in XZ
                        "GOTO/20,0,10\n"            // MULTAX/ON: keeps (0.6,0,0.8)
                        "GOTO/20,0,10,0,-1,1\n"     // orientation only: kept as a move
                        "GOTO/20,0,10,0,-1,1\n"     // zero-length: dropped
                        "MULTAX/OFF\n"
                        "GOTO/30,0,10\n"));  // MULTAX/OFF: back to +Z (TLAXIS default)
  ASSERT_EQ(tp.moves.size(), 4u);
  const Eigen::Vector3d z(0, 0, 1), tilt(0.6, 0, 0.8), yz(0, -std::sqrt(0.5), std::sqrt(0.5));
  ASSERT_TRUE(tp.moves[0].tool_axis_start && tp.moves[0].tool_axis_end);
  EXPECT_TRUE(tp.moves[0].tool_axis_start->isApprox(z));
  EXPECT_TRUE(tp.moves[0].tool_axis_end->isApprox(tilt));
  EXPECT_TRUE(tp.moves[1].tool_axis_start->isApprox(tilt));
  EXPECT_TRUE(tp.moves[1].tool_axis_end->isApprox(tilt));
  EXPECT_TRUE(tp.moves[2].tool_axis_end->isApprox(yz));
  expect_xyz(tp.moves[2].start, 20, 0, 10);
  expect_xyz(tp.moves[2].end, 20, 0, 10);
  EXPECT_TRUE(tp.moves[3].tool_axis_start->isApprox(yz));
  EXPECT_TRUE(tp.moves[3].tool_axis_end->isApprox(z));
  EXPECT_EQ(tp.moves[3].source_line, 9);
}

TEST(Apt, ThreeAxisGotosOfAMultiAxisFileGetPlusZOrTlaxis) {
  const core::ToolPath tp =
      read_apt(write_cl("FEDRAT/100\n"
                        "GOTO/0,0,0\n"
                        "GOTO/1,0,0\n"  // +Z by default, set because the file is multi-axis
                        "TLAXIS/0,1,0\n"
                        "GOTO/2,0,0\n"  // the TLAXIS axis
                        "GOTO/3,0,0,1,0,0\n"));
  ASSERT_EQ(tp.moves.size(), 3u);
  ASSERT_TRUE(tp.moves[0].tool_axis_end);
  EXPECT_TRUE(tp.moves[0].tool_axis_start->isApprox(Eigen::Vector3d::UnitZ()));
  EXPECT_TRUE(tp.moves[0].tool_axis_end->isApprox(Eigen::Vector3d::UnitZ()));
  EXPECT_TRUE(tp.moves[1].tool_axis_end->isApprox(Eigen::Vector3d::UnitY()));
  EXPECT_TRUE(tp.moves[2].tool_axis_end->isApprox(Eigen::Vector3d::UnitX()));
}

TEST(Apt, InchesAreConvertedToMillimetres) {
  const core::ToolPath tp =
      read_apt(write_cl("UNITS/INCHES\n"
                        "CUTTER/0.5,0.125\n"
                        "FROM/1,2,3\n"
                        "FEDRAT/10\n"  // in/min
                        "GOTO/2,2,3\n"
                        "FEDRAT/MMPM,254\n"  // explicit unit wins over UNITS
                        "GOTO/3,2,3\n"
                        "UNITS/MM\n"
                        "FEDRAT/20,IPM\n"
                        "GOTO/0,0,0\n"));
  expect_xyz(tp.initial_position, 25.4, 50.8, 76.2);
  ASSERT_EQ(tp.moves.size(), 3u);
  expect_xyz(tp.moves[0].end, 50.8, 50.8, 76.2);
  EXPECT_DOUBLE_EQ(tp.moves[0].feed_mm_per_min, 254.0);
  EXPECT_DOUBLE_EQ(tp.moves[1].feed_mm_per_min, 254.0);
  expect_xyz(tp.moves[2].end, 0, 0, 0);  // after UNITS/MM
  EXPECT_DOUBLE_EQ(tp.moves[2].feed_mm_per_min, 508.0);
  EXPECT_DOUBLE_EQ(tp.tool_diameter_mm, 12.7);
  EXPECT_DOUBLE_EQ(tp.tool_corner_radius_mm, 3.175);
}

TEST(Apt, CutterAndTldataSetTheTool) {
  EXPECT_DOUBLE_EQ(read_apt(write_cl("CUTTER/10\nGOTO/0,0,0\n")).tool_corner_radius_mm, 0.0);
  const core::ToolPath t7 =
      read_apt(write_cl("CUTTER/10.000000, 5.000000, 0.000000, 5.000000, 0.000000, 0.000000, 30.0\nGOTO/0,0,0\n"));
  EXPECT_DOUBLE_EQ(t7.tool_diameter_mm, 10.0);
  EXPECT_DOUBLE_EQ(t7.tool_corner_radius_mm, 5.0);
  const core::ToolPath nx = read_apt(write_cl("TLDATA/MILL,6.0000,1.0000,50.0000,0.0000,0.0000\nGOTO/0,0,0\n"));
  EXPECT_DOUBLE_EQ(nx.tool_diameter_mm, 6.0);
  EXPECT_DOUBLE_EQ(nx.tool_corner_radius_mm, 1.0);
  EXPECT_NE(apt_error_of("CUTTER/10,6\nGOTO/0,0,0\n").find("prog.apt:1: CUTTER/"), std::string::npos);
}

TEST(Apt, LoadtlSetsTheToolNumberOfLaterMoves) {
  const core::ToolPath tp =
      read_apt(write_cl("GOTO/0,0,0\nLOADTL/7,1\nFEDRAT/100\nGOTO/1,0,0\nLOAD/TOOL,3\nGOTO/2,0,0\n"));
  ASSERT_EQ(tp.moves.size(), 2u);
  EXPECT_EQ(tp.moves[0].tool_number, 7);
  EXPECT_EQ(tp.moves[1].tool_number, 3);
}

// Arcs: the tool starts at `start`, CIRCLE/ about `axis` (counter-clockwise about it), GOTO/ to `end`.
struct ArcCase {
  const char* name;
  const char* circle;  // CIRCLE/ record
  const char* end;     // GOTO/ record
  core::ArcPlane plane;
  double c1, c2;  // centre in the plane's (first, second) coordinates
  int rotation;
};

TEST(Apt, CircleArcsInTheThreePlanesAndBothDirections) {
  // Start (10, 0, 0) about the origin in XY and ZX; (0, 10, 0) in YZ. Quarter turns, checked by hand:
  // counter-clockwise about +Z takes +X to +Y; about +Y takes +Z to +X (and +X to -Z); about +X takes +Y to +Z.
  const ArcCase cases[] = {
      {"XY ccw", "CIRCLE/0,0,0,0,0,1,10", "GOTO/0,10,0", core::ArcPlane::XY, 0, 0, +1},
      {"XY cw", "CIRCLE/0,0,0,0,0,-1,10", "GOTO/0,-10,0", core::ArcPlane::XY, 0, 0, -1},
      {"ZX ccw", "CIRCLE/0,0,0,0,1,0,10", "GOTO/0,0,-10", core::ArcPlane::ZX, 0, 0, +1},
      {"ZX cw", "CIRCLE/0,0,0,0,-1,0,10", "GOTO/0,0,10", core::ArcPlane::ZX, 0, 0, -1},
      {"YZ ccw", "CIRCLE/0,0,0,1,0,0,10", "GOTO/0,0,10", core::ArcPlane::YZ, 0, 0, +1},
      {"YZ cw", "CIRCLE/0,0,0,-1,0,0,10", "GOTO/0,0,-10", core::ArcPlane::YZ, 0, 0, -1},
  };
  for (const ArcCase& c : cases) {
    SCOPED_TRACE(c.name);
    const bool yz = c.plane == core::ArcPlane::YZ;
    const std::string prog =
        std::string("FEDRAT/300\n") + (yz ? "GOTO/0,10,0\n" : "GOTO/10,0,0\n") + c.circle + "\n" + c.end + "\n";
    const core::ToolPath tp = read_apt(write_cl(prog));
    ASSERT_EQ(tp.moves.size(), 1u);
    const core::Move& m = tp.moves[0];
    EXPECT_EQ(m.kind, core::MotionKind::Arc);
    EXPECT_EQ(m.plane, c.plane);
    EXPECT_EQ(m.rotation, c.rotation);
    EXPECT_NEAR(m.centre_mm[0], c.c1, 1e-12);
    EXPECT_NEAR(m.centre_mm[1], c.c2, 1e-12);
    EXPECT_EQ(m.source_line, 3);  // the CIRCLE/ record
    EXPECT_DOUBLE_EQ(m.feed_mm_per_min, 300.0);
    EXPECT_FALSE(m.rapid);
    EXPECT_EQ(m.start, tp.initial_position);
  }
}

// The arc a Move describes, walked as LinuxCNC does: the end point reached with the stated rotation sign passes
// through the mid-point we expect. Checks the centre mapping with an off-origin centre in each plane.
TEST(Apt, CircleCentreMapsToThePlaneCoordinates) {
  // XY: centre (5, 7); ZX: centre (z=3, x=5) -> (3, 5); YZ: centre (y=7, z=3) -> (7, 3).
  {
    const core::ToolPath tp = read_apt(write_cl("FEDRAT/100\nGOTO/15,7,1\nCIRCLE/5,7,1,0,0,1,10\nGOTO/5,17,1\n"));
    ASSERT_EQ(tp.moves.size(), 1u);
    EXPECT_EQ(tp.moves[0].plane, core::ArcPlane::XY);
    EXPECT_TRUE(tp.moves[0].centre_mm.isApprox(Eigen::Vector2d(5, 7)));
    expect_xyz(tp.moves[0].end, 5, 17, 1);
  }
  {
    const core::ToolPath tp = read_apt(write_cl("FEDRAT/100\nGOTO/5,2,13\nCIRCLE/5,2,3,0,1,0,10\nGOTO/15,2,3\n"));
    ASSERT_EQ(tp.moves.size(), 1u);
    EXPECT_EQ(tp.moves[0].plane, core::ArcPlane::ZX);
    EXPECT_TRUE(tp.moves[0].centre_mm.isApprox(Eigen::Vector2d(3, 5)));
    EXPECT_EQ(tp.moves[0].rotation, 1);  // +Z to +X about +Y: counter-clockwise
  }
  {
    const core::ToolPath tp = read_apt(write_cl("FEDRAT/100\nGOTO/0,17,3\nCIRCLE/0,7,3,1,0,0,10\nGOTO/0,7,13\n"));
    ASSERT_EQ(tp.moves.size(), 1u);
    EXPECT_EQ(tp.moves[0].plane, core::ArcPlane::YZ);
    EXPECT_TRUE(tp.moves[0].centre_mm.isApprox(Eigen::Vector2d(7, 3)));
    EXPECT_EQ(tp.moves[0].rotation, 1);
  }
}

TEST(Apt, HelixFullCircleAndNxCircleRecord) {
  // NX CLSF writes tolerance, thickness and tool data after the radius; a helix moves along the axis.
  const core::ToolPath tp = read_apt(
      write_cl("TOOL PATH/PLANAR_MILL,TOOL,MILL_6\n"
               "TLDATA/MILL,6.0000,0.0000,50.0000,0.0000,0.0000\n"
               "MSYS/0.0000,0.0000,0.0000,1.0000000,0.0000000,0.0000000,0.0000000,1.0000000,0.0000000\n"
               "$$ centerline data\n"
               "PAINT/COLOR,186\n"
               "RAPID\n"
               "GOTO/40.0000,30.0000,5.0000\n"
               "FEDRAT/MMPM,250.0000\n"
               "GOTO/60.0000,30.0000,0.0000\n"
               "CIRCLE/40.0000,30.0000,0.0000,0.0000000,0.0000000,1.0000000,20.0000,0.0600,0.5000,6.0000,0.0000\n"
               "GOTO/60.0000,30.0000,0.0000\n"  // full circle
               "CIRCLE/40.0000,30.0000,0.0000,0.0000000,0.0000000,-1.0000000,20.0000,0.0600,0.5000,6.0000,0.0000\n"
               "GOTO/20.0000,30.0000,-2.0000\n"  // half a turn clockwise, 2 mm down: a helix
               "END-OF-PATH\n"));
  ASSERT_EQ(tp.moves.size(), 3u);  // the first GOTO is the initial position
  const core::Move& full = tp.moves[1];
  EXPECT_EQ(full.kind, core::MotionKind::Arc);
  EXPECT_EQ(full.rotation, 1);
  EXPECT_EQ(full.start, full.end);
  const core::Move& helix = tp.moves[2];
  EXPECT_EQ(helix.rotation, -1);
  expect_xyz(helix.end, 20, 30, -2);
  EXPECT_TRUE(helix.centre_mm.isApprox(Eigen::Vector2d(40, 30)));
  EXPECT_EQ(helix.source_line, 12);
  EXPECT_DOUBLE_EQ(tp.tool_diameter_mm, 6.0);
}

TEST(Apt, MovarcAngleCountsFullTurns) {
  // Autodesk's ISO 4343 post: MOVARC/centre, axis, r, ANGLE, swept degrees.
  const core::ToolPath tp =
      read_apt(write_cl("FEDRAT/100\nGOTO/10,0,0\n"
                        "MOVARC/0,0,0,0,0,1,10,ANGLE,720\nGOTO/10,0,-4\n"
                        "MOVARC/0,0,0,0,0,-1,10,ANGLE,90\nGOTO/0,-10,-4\n"));
  ASSERT_EQ(tp.moves.size(), 2u);
  EXPECT_EQ(tp.moves[0].rotation, 2);  // two full turns down a helix
  EXPECT_EQ(tp.moves[1].rotation, -1);
}

TEST(Apt, ArcErrorsNameTheLine) {
  // A tilted axis is read (chords in the circle's plane, apt_nx_test.cpp); its end point must be on the circle: (0, 8,
  // 6) is 9.6 mm along the axis (0, 0.6, 0.8) and 2.8 mm from it.
  const std::string tilted = apt_error_of("FEDRAT/100\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0.6,0.8,10\nGOTO/0,8,6\n");
  EXPECT_NE(tilted.find("prog.apt:4: GOTO/ end point is 2.8 mm from the axis of CIRCLE/ on line 3"), std::string::npos)
      << tilted;
  const std::string radius = apt_error_of("FEDRAT/100\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10\nGOTO/0,12,0\n");
  EXPECT_NE(radius.find("prog.apt:4: GOTO/ end point is 12 mm from the centre of CIRCLE/ on line 3"), std::string::npos)
      << radius;
  const std::string dangling = apt_error_of("FEDRAT/100\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10\n");
  EXPECT_NE(dangling.find("prog.apt:3: CIRCLE/ is not followed by its GOTO/"), std::string::npos) << dangling;
  const std::string nostart = apt_error_of("CIRCLE/0,0,0,0,0,1,10\nGOTO/0,10,0\n");
  EXPECT_NE(nostart.find("prog.apt:1: CIRCLE/ before any FROM/ or GOTO/"), std::string::npos) << nostart;
  const std::string zero_axis = apt_error_of("FEDRAT/100\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,0,10\nGOTO/0,10,0\n");
  EXPECT_NE(zero_axis.find("prog.apt:3: CIRCLE/ axis vector (0, 0, 0) has zero length"), std::string::npos)
      << zero_axis;
}

TEST(Apt, ContinuationLinesAndComments) {
  // CATIA-style header: comments, PARTNO without a slash, a bare MULTAX, continued CUTTER and TOOLNO records.
  const core::ToolPath tp =
      read_apt(write_cl("$$ -----------------------------------------------------------------\n"      // 1
                        "$$*CATIA0\n"                                                                 // 2
                        "PARTNO Part1/op 10\n"                                                        // 3
                        "$$ OPERATION NAME : Tool Change.1\n"                                         // 4
                        "MULTAX\n"                                                                    // 5
                        "CUTTER/ 8.000000, 4.000000, 0.000000, 4.000000, 0.000000,$\n"                // 6
                        "        0.000000, 40.000000\n"                                               // 7
                        "TOOLNO/1,MILL,1,0,   14.106000,  100.000000,$\n"                             // 8
                        "  100.000000,,   20.000000,$\n"                                              // 9
                        "ON,,NOTE\n"                                                                  // 10
                        "TPRINT/T1 Ball Mill D 8\n"                                                   // 11
                        "LOADTL/1,1,1\n"                                                              // 12
                        "SPINDL/   7000.0000,RPM,CLW\n"                                               // 13
                        "FEDRAT/ 1000.0000,MMPM\n"                                                    // 14
                        "GOTO  /   10.00000,   20.00000,    5.00000, 0.000000, 0.000000, 1.000000\n"  // 15
                        "GOTO  /   10.00000,$ $$ x only\r\n"                                          // 16 (CRLF too)
                        "   25.00000,    5.00000,$\r\n"                                               // 17
                        " 0.000000, 0.000000, 1.000000 $$ end of the record\r\n"                      // 18
                        "PPRINT/'OPERATION 2: $$ NOT A COMMENT IN APT, BUT HARMLESS'\n"               // 19
                        "COOLNT/ON\n"                                                                 // 20
                        "GOTO/10,25,0\n"                                                              // 21
                        "FINI\n"                                                                      // 22
                        "GARBAGE AFTER FINI IS NOT READ\n"));
  EXPECT_DOUBLE_EQ(tp.tool_diameter_mm, 8.0);
  EXPECT_DOUBLE_EQ(tp.tool_corner_radius_mm, 4.0);
  expect_xyz(tp.initial_position, 10, 20, 5);
  ASSERT_EQ(tp.moves.size(), 2u);
  EXPECT_EQ(tp.moves[0].source_line, 16);  // the first line of the continued record
  expect_xyz(tp.moves[0].end, 10, 25, 5);
  EXPECT_EQ(tp.moves[1].source_line, 21);
  EXPECT_EQ(tp.moves[1].tool_number, 1);
}

TEST(Apt, GodltaGohomeAndLaterFrom) {
  const core::ToolPath tp =
      read_apt(write_cl("FROM/0,0,50\n"
                        "FEDRAT/100\n"
                        "GOTO/10,0,5\n"
                        "GODLTA/0,0,-5\n"    // incremental
                        "GODLTA/3\n"         // 3 mm along the tool axis (+Z)
                        "GOHOME\n"           // back to the FROM point, at feed
                        "FROM/20,0,50\n"));  // a later FROM is a rapid to the new start
  ASSERT_EQ(tp.moves.size(), 5u);
  expect_xyz(tp.moves[1].end, 10, 0, 0);
  expect_xyz(tp.moves[2].end, 10, 0, 3);
  expect_xyz(tp.moves[3].end, 0, 0, 50);
  EXPECT_FALSE(tp.moves[3].rapid);
  expect_xyz(tp.moves[4].end, 20, 0, 50);
  EXPECT_TRUE(tp.moves[4].rapid);
}

TEST(Apt, ZeroLengthMovesAreDropped) {
  const core::ToolPath tp = read_apt(write_cl("FEDRAT/100\nGOTO/1,2,3\nGOTO/1,2,3\nRAPID\nGOTO/1,2,3\nGOTO/1,2,4\n"));
  ASSERT_EQ(tp.moves.size(), 1u);
  EXPECT_FALSE(tp.moves[0].rapid);  // the RAPID was spent on the dropped move
  EXPECT_EQ(tp.moves[0].source_line, 6);
}

TEST(Apt, ReadProgramDispatchesClExtensions) {
  for (const char* name : {"a.apt", "b.cl", "c.CLS", "d.aptsource"}) {
    const core::ToolPath tp = read_program(write_cl("GOTO/0,0,0\nFEDRAT/10\nGOTO/1,0,0\n", name));
    EXPECT_EQ(tp.moves.size(), 1u) << name;
  }
}

// Each bad program and the text its error must contain: "file:line: what".
TEST(Apt, ErrorsNameTheFileLineAndWord) {
  const struct {
    const char* program;
    const char* expected;
  } cases[] = {
      {"GOTO/0,0,0\nFOOBAR/1,2\n", "prog.apt:2: unknown APT major word 'FOOBAR'"},
      {"GOTO/0,0,0\nGOFWD/PL1,PAST,PL2\n", "prog.apt:2: 'GOFWD' moves the tool"},
      {"GOTO/0,0,0\nCYCLE/DRILL,5,MMPM,100,2\n", "prog.apt:2: CYCLE/DRILL"},
      {"GOTO/0,0,0\nTRACUT/MX1\n", "prog.apt:2: 'TRACUT'"},
      {"GOTO/1,2\n", "prog.apt:1: GOTO/ has 2 values (expected x, y, z or x, y, z, i, j, k)"},
      {"GOTO/1,2,3,4\n", "prog.apt:1: GOTO/ has 4 values"},
      {"GOTO/1,,3\n", "prog.apt:1: GOTO/ value 2 \"\" is not a number"},
      {"GOTO/1,2,abc\n", "prog.apt:1: GOTO/ value 3 \"ABC\" is not a number"},
      {"GOTO/1,2,1e400\n", "prog.apt:1: GOTO/ value 3 \"1E400\" is out of the range of a double"},
      {"GOTO/1,2,NaN\n", "prog.apt:1: GOTO/ value 3 \"NAN\" is not a finite number"},
      {"GOTO/1,2,-inf\n", "prog.apt:1: GOTO/ value 3 \"-INF\" is not a finite number"},
      {"GOTO/1,2,3,0,0,0\n", "prog.apt:1: GOTO/ axis vector (0, 0, 0) has zero length"},
      {"GOTO/1,2,3,1e300,1e300,0\n", "prog.apt:1: GOTO/ axis vector (1e+300, 1e+300, 0) has no finite length"},
      {"UNITS/INCHES\nGOTO/1e308,0,0\n", "prog.apt:2: GOTO/ position is out of range"},
      {"GOTO/0,0,0\nGOTO/1,0,0\n", "prog.apt:2: GOTO/ cuts at feed before any FEDRAT/"},
      {"FEDRAT/0\n", "prog.apt:1: FEDRAT/ feed 0 is not positive"},
      {"FEDRAT/-5,MMPM\n", "prog.apt:1: FEDRAT/ feed -5 is not positive"},
      {"FEDRAT/100,IPR\n", "prog.apt:1: FEDRAT/ IPR feeds are not supported"},
      {"FEDRAT/MMPM\n", "prog.apt:1: FEDRAT/ has no feed value"},
      {"FEDRAT/100,200\n", "prog.apt:1: FEDRAT/ has an unexpected value \"200\""},
      {"UNITS/FEET\n", "prog.apt:1: UNITS/FEET is not a unit"},
      {"MULTAX/MAYBE\n", "prog.apt:1: MULTAX/MAYBE"},
      {"TLAXIS/0,0\n", "prog.apt:1: TLAXIS/ has 2 values"},
      {"LOADTL/1.5\n", "prog.apt:1: LOADTL/ tool number 1.5 is not a whole number"},
      {"GOHOME\n", "prog.apt:1: GOHOME without a FROM/ point"},
      {"GODLTA/1,2,3\n", "prog.apt:1: GODLTA/ before any FROM/ or GOTO/"},
      {"RAPID/FAST\n", "prog.apt:1: RAPID takes no values"},
      {"FEDRAT/10\nGOTO/10,0,0\nRAPID\nCIRCLE/0,0,0,0,0,1,10\nGOTO/0,10,0\n", "prog.apt:4: CIRCLE/ follows RAPID"},
      {"GOTO/0,0,0\nCUTTER/1,2,$\n", "prog.apt:2: CUTTER/ diameter 1 mm, corner radius 2 mm"},
      {"", "prog.apt: no FROM/ or GOTO/ record"},
      {"$$ only a comment\nPARTNO X\nFINI\n", "prog.apt: no FROM/ or GOTO/ record"},
      {"GOTO/0,0,0\n/1,2,3\n", "prog.apt:2: record \"1,2,3\" has no major word"},
      {"FEDRAT/1\nGOTO/1,0,0\nMOVARC/0,0,0,0,0,1,1,ANGLE,1e300\nGOTO/1,0,0\n",
       "prog.apt:3: MOVARC/ ANGLE 1E300 is out of range"},
      {"FEDRAT/1\nGOTO/1,0,0\nMOVARC/0,0,0,0,0,1,1,ANGLE,-90\nGOTO/1,0,0\n",
       "prog.apt:3: MOVARC/ ANGLE -90 is out of range"},
      {"GOTO/0,0,0\nG\x01\xff/1\n",
       "prog.apt:2: unknown APT major word 'G?"
       "?'"},
  };
  for (const auto& c : cases) {
    const std::string msg = apt_error_of(c.program);
    EXPECT_NE(msg.find(c.expected), std::string::npos) << "program:\n" << c.program << "\nmessage: " << msg;
    // Every message starts with the file's path.
    EXPECT_EQ(msg.rfind(write_cl("").string(), 0), 0u) << msg;
  }
}

TEST(Apt, MissingFileIsAnErrorNamingIt) {
  try {
    read_apt("/nonexistent/dir/part.apt");
    FAIL() << "no error";
  } catch (const core::Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("/nonexistent/dir/part.apt: cannot open", 0), 0u) << e.what();
  }
}

}  // namespace
}  // namespace vmsim::program
