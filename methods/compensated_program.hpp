#pragma once
// The compensated NC program of `vmsim compensate`: the original program's own moves, in order, with the same feeds
// and feed modes, each programmed point (move end) moved by the correction the compensation found at the setpoint
// nearest to it, so that an NC's interpolator re-times it as it times the original (the predictive-compensation paper
// section 5 sends its compensated points to the CNC). Arcs stay arcs about their programmed centre, split into pieces
// that follow the correction along the arc (each a spiral between two corrected points, as LinuxCNC reads an arc whose
// radii at start and end differ; the .cpp says how long); on five-axis chains an arc of a CL or tool-centre-point
// program becomes the points of its axis-space image (in inverse-time feed, each piece of an arc gets the share of the
// move's time its swept angle has; of an image, an equal share).
#include "motion/kinematics.hpp"
#include "core/machine.hpp"
#include "core/setpoints.hpp"
#include "core/toolpath.hpp"

#include <Eigen/Core>

#include <string>

namespace vmsim::methods {

struct CompensatedProgramInput {
  const core::ToolPath* program = nullptr;       // as read (workpiece frame)
  const core::ToolPath* axis_path = nullptr;     // motion::toolpath_in_axis_space(*program)
  const core::Setpoints* setpoints = nullptr;    // the original setpoints (move_index)
  const Eigen::MatrixXd* compensated = nullptr;  // the compensated setpoints, samples x axes
  const Eigen::MatrixXd* command_tip = nullptr;  // tool tips of the original setpoints, samples x 3
  const core::Machine* machine = nullptr;
  const motion::Kinematics* kinematics = nullptr;
  double chord_tolerance_mm = 0.5e-3;  // arcs written as G1 chords within this sag
  std::string title;                   // first comment line
};

struct CompensatedProgram {
  std::string text;
  std::string extension;  // "ngc" (G-code) or "cl" (APT CL, for CL programs)
  int blocks = 0;         // motion blocks written
  double largest_tip_correction_mm = 0.0;
  double largest_axis_correction_rad = 0.0;  // tool axis (five-axis chains)
};

// The longest piece (rad) of a compensated arc of this radius: short enough that the interpolator's blend where two
// pieces meet stays within 0.01 um of the arc, at most a quarter turn.
double arc_piece_max_angle_rad(double radius_mm);

// G-code programs: G-code (G0/G1, G93/G94 as the original; on five-axis chains the words of the original's own
// convention: tool-centre-point X Y Z with the rotary words, or joint words). APT CL programs: CL (GOTO/ tip and tool
// axis, FEDRAT, RAPID as the original).
CompensatedProgram write_compensated_program(const CompensatedProgramInput& in);

// The same correction written as G-code in tool-centre-point form with the rotary words (X Y Z: tool tip in the
// workpiece frame; A B C: the rotary axes), for a controller with a five-axis transformation (Siemens TRAORI, LinuxCNC
// M428): the original's moves, feeds and corrected points. Five-axis chains only.
CompensatedProgram write_compensated_tcp_gcode(const CompensatedProgramInput& in);

// The compensated setpoints themselves as a program (vmsim compensate --dense-program): the tool tip (and the rotary
// words) of every setpoint, one block per Te in inverse-time feed (G93: F = 1 / block duration in minutes), for an
// NC that replays blocks as timed. Rotary words: every rotary axis on five-axis work (`five_axis`), else those that
// move. `tlo_mm`: each setpoint's tool length offset.
std::string write_dense_program(const Eigen::MatrixXd& setpoints, const Eigen::VectorXd& tlo_mm,
                                const core::Machine& machine, const motion::Kinematics& kinematics, double period_s,
                                bool five_axis, const std::string& title);

}  // namespace vmsim::methods
