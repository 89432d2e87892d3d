#pragma once
// Machine kinematics: between what the program asks of the tool (tip and axis in the workpiece frame) and what
// the machine's axes do. This file holds the Cartesian 3-axis machine ("xyz"): X Y Z carry the tool tip plus the
// tool length offset along Z; rotary axes, when the machine has them, are commanded directly.
#include "core/machine.hpp"
#include "core/toolpath.hpp"

namespace vmsim::core {

// Axis positions (program axis order, mm and rad) of a controlled point under a tool length offset.
Vec6 axes_from_tip(const Vec6& tip, double tool_length_offset_mm, const Machine& machine);
Vec6 tip_from_axes(const Vec6& axes, double tool_length_offset_mm, const Machine& machine);

// The ToolPath with every position (and arc centre) in axis coordinates: moves then join end to start.
// Throws core::Error for a machine kinematics this function does not know.
ToolPath toolpath_in_axis_space(const ToolPath& path, const Machine& machine);

}  // namespace vmsim::core
