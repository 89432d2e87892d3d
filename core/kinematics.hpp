#pragma once
// Machine kinematics: between what the program asks of the tool (tip and axis in the workpiece frame) and what
// the machine's axes do. The interface every machine uses; this file holds the Cartesian 3-axis machine
// ("xyz"): X Y Z carry the tool tip plus the tool length offset along Z, and rotary axes, when the machine has
// them, are commanded directly. The five-axis chains come with their own issue.
#include "core/machine.hpp"
#include "core/toolpath.hpp"

#include <Eigen/Core>

#include <memory>

namespace vmsim::core {

struct ToolPose {
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // unit vector from the tip towards the spindle
};

class Kinematics {
 public:
  virtual ~Kinematics() = default;
  // Axis positions (machine-file order; mm, rad) to the tool pose in the workpiece frame, for a tool whose tip is
  // `tool_length_offset_mm` from the controlled point along the tool axis.
  virtual ToolPose forward(const Eigen::VectorXd& axes, double tool_length_offset_mm) const = 0;
  // The inverse; `near` (machine-file order) picks among several solutions and fixes the axes the pose leaves free.
  virtual Eigen::VectorXd inverse(const ToolPose& pose, double tool_length_offset_mm,
                                  const Eigen::VectorXd& near) const = 0;
};

// The machine's kinematics; throws core::Error naming the machine file for a chain vmsim does not know.
std::unique_ptr<Kinematics> make_kinematics(const Machine& machine);

// Program-axis positions (Vec6) of a controlled point under a tool length offset, and back (3-axis machines).
Vec6 axes_from_tip(const Vec6& tip, double tool_length_offset_mm, const Machine& machine);
Vec6 tip_from_axes(const Vec6& axes, double tool_length_offset_mm, const Machine& machine);

// The ToolPath with every position (and arc centre) in axis coordinates: moves then join end to start.
ToolPath toolpath_in_axis_space(const ToolPath& path, const Machine& machine);

}  // namespace vmsim::core
