#pragma once
// ToolPath: what a program asks for, in the workpiece frame, before any interpolation.
// Produced by the program readers (G-code, APT CL), consumed by the interpolator.
#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::core {

// Program axes in a fixed order: X Y Z (mm), A B C (rad).
using Vec6 = Eigen::Matrix<double, 6, 1>;
enum ProgramAxis : int { kX = 0, kY = 1, kZ = 2, kA = 3, kB = 4, kC = 5 };

enum class MotionKind : std::uint8_t { Line, Arc };
// Arc planes with LinuxCNC's axis order: XY = (x, y) about z (G17), ZX = (z, x) about y (G18),
// YZ = (y, z) about x (G19).
enum class ArcPlane : std::uint8_t { XY, ZX, YZ };
enum class FeedMode : std::uint8_t { UnitsPerMinute, InverseTime };

struct Move {
  MotionKind kind = MotionKind::Line;
  bool rapid = false;
  // Controlled point (the tool tip when the tool length offset matches the tool) with every work offset
  // applied, X Y Z in mm, and the rotary axes A B C in rad.
  Vec6 start = Vec6::Zero();
  Vec6 end = Vec6::Zero();

  // Arcs and helices (kind == Arc): centre in the plane's two coordinates, (first, second) as in ArcPlane;
  // the plane's normal coordinate and the rotary axes move linearly with the swept angle.
  ArcPlane plane = ArcPlane::XY;
  Eigen::Vector2d centre_mm = Eigen::Vector2d::Zero();
  // LinuxCNC's ARC_FEED rotation: > 0 counter-clockwise seen from the plane normal's positive side, < 0 clockwise;
  // |rotation| - 1 extra full turns (1 = up to one full turn; start == end is a full circle).
  int rotation = 0;

  // Feed: under UnitsPerMinute, feed_mm_per_min is the programmed point's speed (deg/min for moves of the rotary
  // axes only, as LinuxCNC does); under InverseTime the move must take 1 / inverse_time_per_min minutes.
  FeedMode feed_mode = FeedMode::UnitsPerMinute;
  double feed_mm_per_min = 0.0;
  double inverse_time_per_min = 0.0;

  // Tool axis (unit vector, workpiece frame) at the start and end of the move, when the program gives it
  // (APT CL GOTO/x,y,z,i,j,k). Empty for programs that move the machine's axes directly.
  std::optional<Eigen::Vector3d> tool_axis_start, tool_axis_end;

  // G-code on a five-axis machine (kinematics = "chain"): true when the program's X Y Z are the tool tip in the
  // workpiece frame and A B C the rotary axes (tool-centre-point programming: LinuxCNC's M428 on xyzac-trt, Siemens
  // TRAORI); false when the words are the machine's axis positions themselves. Set from the job ([job] tcp).
  bool tcp = false;

  // Axis-space moves of chain machines only (motion::toolpath_in_axis_space): when the move's image in axis space is
  // not a straight line (the rotary axes turn while the tip follows the programmed path), the axis positions on the
  // exact image in between, in order, and their programmed-path parameter s (the fraction of the move's programmed
  // duration; the point the program asks for at s), non-decreasing in [0, 1). Axis-space straight segments
  // start -> via -> end keep the tool tip within the conversion's tolerance of the programmed path. Equal s values
  // (0 included) mark a turn of the rotary axis that is free at a singular pose, the tool pose held: the motion needs
  // the time the axes take, which the programmed feed does not give. Empty when the move is straight in axis space.
  std::vector<Vec6> via;
  std::vector<double> via_s;
  // Axis-space moves of chain machines only: how far the tool pose in the workpiece frame moves per unit of path
  // space (core/smooth_path: mm for X Y Z, degrees for A B C) along this move, as bounds the interpolator's corner
  // blends use to keep its tolerance on the tool tip (and on the tool axis, counted at 100 mm from the tip):
  // tip_per_mm bounds |d tip| / |d(X Y Z)| (the linear axes' map; exactly 1 when it is orthonormal), tip_per_deg the
  // tip's (or the tool axis' times 100 mm) motion per degree of A, B, C (0 on machines without chains).
  double tip_per_mm = 1.0;
  Eigen::Vector3d tip_per_deg = Eigen::Vector3d::Zero();

  int tool_number = 0;               // active tool (T... M6), 0 = none
  double tool_length_offset_mm = 0;  // active tool length offset along the tool axis (G43), 0 under G49
  int source_line = 0;               // 1-based line of the program that made this move
};

// A tool a CL program names (APT TLDATA/MILL, CUTTER/), as its moves' Move::tool_number refers to it.
struct ProgramTool {
  int number = 0;  // the tool_number of the moves it cuts
  double diameter_mm = 0.0;
  double corner_radius_mm = 0.0;
  double length_mm = 0.0;  // TLDATA/MILL's length; 0 = unknown
  int line = 0;            // the record that first gave this geometry
  // Per stretch of consecutive moves cut by it, the line of the geometry record in force at its first move.
  std::vector<int> stretch_lines;
  // The number is the program's (LOAD/TOOL, LOADTL); otherwise vmsim's, in order of first appearance.
  bool numbered_by_program = false;
};

// Consecutive moves join in machine coordinates: a move starts where the previous one ended, plus any change of
// the tool length offset (G43/G49 moves the controlled point, not the axes). On a 3-axis machine the Z axis
// carries tip + tool_length_offset_mm (core/kinematics).
struct ToolPath {
  std::string source_path;               // the program file as the user named it
  std::vector<Move> moves;               // in program order
  Vec6 initial_position = Vec6::Zero();  // controlled point before the first move (no tool length offset)
  // Tool diameter from the program or tool table when known (APT CUTTER/, LinuxCNC tool table D); 0 = unknown.
  double tool_diameter_mm = 0.0;
  double tool_corner_radius_mm = 0.0;
  double tool_length_mm = 0.0;  // APT TLDATA/MILL's length; 0 = unknown
  int tool_line = 0;            // the line the program's tool was read from (APT CUTTER/, TLDATA/); 0 = none
  // CL programs: every tool geometry the moves are cut with, in order of first use (the first is tool_diameter_mm's).
  // A program that names one geometry and no LOAD/TOOL keeps tool_number 0 (no tool change); several geometries
  // without LOAD/TOOL are numbered 1, 2, ... in order of first appearance (program/apt.hpp).
  std::vector<ProgramTool> program_tools;
  // 840D T="name": the reader numbers named tools 1, 2, ... in order of first call; tool_names[n - 1] is tool n's name.
  std::vector<std::string> tool_names;
  // The interpolation tolerance the program itself sets (Sinumerik CYCLE832: the smallest in force for a feed move);
  // a job without [interpolation] tolerance_mm interpolates with it. Empty: the program sets none.
  std::optional<double> program_tolerance_mm;
  // What the reader accepted without modelling it (Sinumerik and APT, lenient; APT units), "file:line: what".
  std::vector<std::string> warnings;
};

}  // namespace vmsim::core
