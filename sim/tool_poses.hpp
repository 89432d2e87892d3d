#pragma once
// Tool poses of a motion for material removal (vmsim run): tool tip and tool axis in the workpiece frame, from the
// axis positions every Te (the drives' actual positions or the setpoints) through the machine's forward transform,
// or from the programmed path itself. On a five-axis ("chain") machine the tool axis turns: the PoseTrack then holds
// the axis per sample and removal/track.hpp sub-steps the turn within the track tolerance.
#include "motion/kinematics.hpp"
#include "core/machine.hpp"
#include "core/toolpath.hpp"
#include "removal/swept_tool.hpp"
#include "removal/track.hpp"

#include <Eigen/Core>

#include <functional>
#include <optional>
#include <vector>

namespace vmsim::sim {

// Whether the tool axis holds still over these rows: every rotary axis stays exactly (bitwise) where it starts and
// every pose's axis (axis_rows: forward()'s axis per row) is the first's. No rows: true.
bool tool_axis_constant(const core::Machine& machine, const Eigen::MatrixXd& axes, const Eigen::MatrixXd& axis_rows);

// Axis positions every Te (samples x machine axes, mm and rad, machine-file order) to tool poses: row k's tip and
// axis are kin.forward(axes.row(k), tool_length_offset(k)). With `velocities` (same shape, mm/s and rad/s) the tip
// velocity is the chain's Jacobian times them (Kinematics::tip_velocity), so the track follows the cubic Hermite curve
// between samples. When every rotary axis stays exactly where it starts and the tool axis is the same at every
// sample, the track has one constant axis (3-axis motion: the sweeps are those of a 3-axis machine); otherwise it
// holds the axis per sample.
removal::PoseTrack pose_track_from_axes(const motion::Kinematics& kin, const core::Machine& machine,
                                        const Eigen::MatrixXd& axes, const Eigen::MatrixXd* velocities, double period_s,
                                        const std::function<double(Eigen::Index)>& tool_length_offset);

// The programmed path of a chain machine's program, as tool poses in the workpiece frame (the "program" motion):
// - APT CL moves: the tip along the programmed line or arc, the tool axis on the great circle between its end values;
// - G-code moves under tool-centre-point programming (Move::tcp): the tip along the programmed line or arc, the
//   rotary words linear in the same parameter, the tool axis the forward transform's at those rotary positions;
// - other G-code moves (joint programming): the axes along the move in axis space (`axis_space`, the program through
//   motion::toolpath_in_axis_space, one move per program move) and the pose their forward transform.
// Each move is sampled by bisection until the pose at the middle of every piece lies within `tolerance_mm` of the
// piece's chord and great-circle middle (tip distance + tool.reach() x axis distance) and no piece turns the axis by
// more than 5 degrees or a rotary axis by more than 10 degrees. The chord's midpoint deviation is the largest
// deviation of a circle's chord (arcs, C turns) and within a factor (1 + O(theta^2)) of it for the smooth curves of a
// move, so the track's chords stay within about tolerance_mm of the programmed poses.
removal::PoseTrack program_pose_track(const core::ToolPath& program, const core::ToolPath& axis_space,
                                      const motion::Kinematics& kin, const core::Machine& machine,
                                      const removal::Tool& tool, double tolerance_mm);
// The same for a program that changes tools: move m is sampled with the reach of tools[move_tool[m]] and its poses
// carry that tool (PoseTrack::tool: the first pose, the first move's start, its tool). `pose_move`, when given,
// receives each pose's move index. Empty `move_tool`: tools[0] cuts every move and PoseTrack::tool stays empty.
removal::PoseTrack program_pose_track(const core::ToolPath& program, const core::ToolPath& axis_space,
                                      const motion::Kinematics& kin, const core::Machine& machine,
                                      const std::vector<removal::Tool>& tools, const std::vector<int>& move_tool,
                                      double tolerance_mm, std::vector<int>* pose_move = nullptr);

// True when a program needs the five-axis track: some move gives a tool axis (CL), is tool-centre-point G-code, or has
// a rotary word other than 0. Otherwise the programmed path is a 3-axis path of the tool tip in the workpiece frame.
bool program_turns_tool(const core::ToolPath& program);

}  // namespace vmsim::sim
