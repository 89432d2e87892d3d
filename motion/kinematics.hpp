#pragma once
// Machine kinematics: between what the program asks of the tool (tip and axis in the workpiece frame) and what
// the machine's axes do. Two machines: the Cartesian 3-axis machine ("xyz": X Y Z carry the tool tip plus the tool
// length offset along Z; rotary axes, when the machine has them, are commanded directly), and kinematic chains
// ("chain": the joints from the machine's base to the workpiece and to the tool, parts/README.md), with the forward
// transform for any chain and the closed-form inverse for the common five-axis families.
#include "core/machine.hpp"
#include "core/toolpath.hpp"

#include <Eigen/Core>

#include <memory>

namespace vmsim::motion {

struct ToolPose {
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // unit vector from the tip towards the spindle
};

// Which inverse a chain has, found from the chain itself (never written in the machine file): where its two rotary
// joints sit. The inverse solves the tool axis for the two rotary angles in closed form (two solutions in general),
// then the linear axes for the tip.
enum class KinematicFamily {
  Cartesian,   // "xyz", or a chain without rotary joints: the tool axis never turns
  TableTable,  // both rotary joints carry the workpiece (A tilting + C rotary: Mikron UCP 710, LinuxCNC xyzac-trt; B/C)
  HeadTable,   // one rotary joint carries the workpiece, one the tool
  HeadHead,    // both rotary joints carry the tool (fork heads)
  ForwardOnly,  // any other chain (one or three rotary joints, parallel rotary axes, ...): no inverse
};
const char* family_name(KinematicFamily family);

class Kinematics {
 public:
  virtual ~Kinematics() = default;
  // Axis positions (machine-file order; mm, rad) to the tool pose in the workpiece frame, for a tool whose tip is
  // `tool_length_offset_mm` from the controlled point (the gauge point) along the tool axis. Allocation-free: it runs
  // for every sample of a job.
  virtual ToolPose forward(const Eigen::VectorXd& axes, double tool_length_offset_mm) const = 0;
  // The inverse; `near` (machine-file order) picks among several solutions and fixes the axes the pose leaves free.
  // Chain machines: the solution whose rotary angles are closest to near's (each angle the 2 pi equivalent closest to
  // near's, within the axis' travel), see kinematics.cpp. Throws core::Error when no solution is within the machine's
  // travels or the chain has no inverse (KinematicFamily::ForwardOnly).
  virtual Eigen::VectorXd inverse(const ToolPose& pose, double tool_length_offset_mm,
                                  const Eigen::VectorXd& near) const = 0;
  // The linear axes that put the tool tip at `tip_mm` (workpiece frame) with every rotary axis where `axes` has it:
  // returns `axes` with X Y Z replaced. This is the whole inverse of tool-centre-point programs, whose rotary words
  // are the rotary axes; it exists for every chain (ForwardOnly ones too).
  virtual Eigen::VectorXd place_tip(const Eigen::Vector3d& tip_mm, double tool_length_offset_mm,
                                    const Eigen::VectorXd& axes) const = 0;
  // Velocity of the tool tip relative to the workpiece, in the workpiece frame (mm/s), for axis velocities
  // `axis_velocities` (machine-file order; mm/s, rad/s) at `axes`: the chain's Jacobian times the velocities.
  virtual Eigen::Vector3d tip_velocity(const Eigen::VectorXd& axes, const Eigen::VectorXd& axis_velocities,
                                       double tool_length_offset_mm) const = 0;
  // Many samples at once (issue 21: a run's millions): row k of tip_mm (and of axis, when given) is
  // forward(axes.row(k), tool_length_offset_mm[k]), bit for bit, with no temporary per row; a chain reuses a rotary
  // joint's cosine and sine while its angle repeats bit for bit (a held rotary axis costs no sin/cos per row).
  // tip_mm and axis must have axes.rows() rows and 3 columns (axis may be empty: not wanted). Throws core::Error
  // otherwise.
  virtual void forward_rows(const Eigen::Ref<const Eigen::MatrixXd>& axes,
                            const Eigen::Ref<const Eigen::VectorXd>& tool_length_offset_mm,
                            Eigen::Ref<Eigen::MatrixXd> tip_mm, Eigen::Ref<Eigen::MatrixXd> axis) const;
  // Row k of tip_velocity_mm_per_s is tip_velocity(axes.row(k), axis_velocities.row(k), tool_length_offset_mm[k]),
  // bit for bit (as forward_rows, a repeated rotary angle reuses its rotation).
  virtual void tip_velocity_rows(const Eigen::Ref<const Eigen::MatrixXd>& axes,
                                 const Eigen::Ref<const Eigen::MatrixXd>& axis_velocities,
                                 const Eigen::Ref<const Eigen::VectorXd>& tool_length_offset_mm,
                                 Eigen::Ref<Eigen::MatrixXd> tip_velocity_mm_per_s) const;
  virtual KinematicFamily family() const = 0;
};

// The machine's kinematics; throws core::Error naming the machine file for a chain vmsim does not know.
std::unique_ptr<Kinematics> make_kinematics(const core::Machine& machine);

// Program-axis positions (Vec6) of a controlled point under a tool length offset, and back (3-axis machines).
core::Vec6 axes_from_tip(const core::Vec6& tip, double tool_length_offset_mm, const core::Machine& machine);
core::Vec6 tip_from_axes(const core::Vec6& axes, double tool_length_offset_mm, const core::Machine& machine);

struct AxisSpaceOptions {
  // Chain machines: the largest distance between the tool tip on the axis-space polyline (start, via..., end) and
  // the programmed path at the same path parameter; the tool axis is held to tolerance_mm / 100 mm rad (a point
  // 100 mm up the tool stays within the tolerance as well).
  double tolerance_mm = 1e-3;
};

// The ToolPath with every position (and arc centre) in axis coordinates (Vec6 by program axis: the machine's X Y Z
// in mm and A B C in rad); moves then join end to start. One axis-space move per program move, in order (Setpoints'
// move_index keeps naming program moves).
// - "xyz" machines: X Y Z carry the tip plus the tool length offset along Z.
// - "chain" machines, by move:
//   * APT CL moves (tool_axis_start/end given): tip and tool axis in the workpiece frame, through the inverse; the tip
//     moves along the programmed line or arc and the tool axis along the great circle between its end values;
//   * G-code moves with Move::tcp: X Y Z are the tip in the workpiece frame and A B C the rotary axes (LinuxCNC
//     xyzac-trt in M428 mode); the rotary words move linearly with the path parameter, as the tip does;
//   * other G-code moves: the words are the axes themselves (joint programming: LinuxCNC's identity kinematics after
//     M429), with the tool length offset added to Z as on "xyz".
//   A CL or TCP move whose axis-space image is straight (the rotary axes do not turn) stays one line, and an arc stays
//   an arc when its plane maps onto XY, ZX or YZ of the axes; otherwise the move is a line with via points on its
//   exact image (Move::via, via_s) within options.tolerance_mm. A CL move that leaves a singular pose (tool axis along
//   the free rotary axis) in a direction needing another angle of that axis first turns it on the spot: via points at
//   one s, the tool pose held. Where the rotary axes turn, a feed per minute becomes the inverse-time feed of the
//   programmed duration (RS274/NGC: the tip's length over F, or the rotary words' angle over F when the tip stays
//   put), because the programmed feed is the tip's speed in the workpiece frame, not the axes' speed.
//   Continuity: TCP and joint programs' rotary words are the axes as written; CL moves solve each point from the one
//   before (the inverse's near), so the rotary axes never jump by 2 pi along a path. Chain moves keep their
//   tool_length_offset_mm (forward() needs the tool's length); on "xyz" it is consumed into Z and set to 0.
//   The path's initial_position becomes the first move's axis-space start when that move is a CL or TCP move.
//   Every chain move gets Move::tip_per_mm and tip_per_deg (the chain's Jacobian along it), with which the
//   interpolator's corner blends keep its tolerance on the tool tip (core/smooth_path).
//   Errors (unreachable poses, travel, a start that does not join the previous move) name the program file and line.
core::ToolPath toolpath_in_axis_space(const core::ToolPath& path, const core::Machine& machine,
                                      const AxisSpaceOptions& options = {});

}  // namespace vmsim::motion
