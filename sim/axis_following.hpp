#pragma once
// Follow-up (tracking) error of each axis: the setpoint the drive was sent minus where the axis is (the feed-drive
// simulation paper §4: "the deviations measured on the axes", about 0.001 degrees on the Mikron's rotary tables), and
// the tool axis' angle between the commanded and the actual pose.
#include "motion/kinematics.hpp"
#include "core/machine.hpp"
#include "core/setpoints.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <functional>

namespace vmsim::sim {

// Per machine axis over the setpoint samples (row k of `actual` is the axis when setpoint k is sent): largest |e|
// and RMS of e = setpoint - actual, in mm (linear axes) or degrees (rotary axes, keys *_deg), and the sample time of
// the largest. With `kin`, also "tool_axis": the largest and RMS angle (degrees) between the tool axis of the
// commanded and of the actual axis positions, in the workpiece frame.
nlohmann::json axis_following_json(const core::Machine& machine, const core::Setpoints& setpoints,
                                   const Eigen::MatrixXd& actual, const motion::Kinematics* kin,
                                   const std::function<double(Eigen::Index)>& tool_length_offset);

}  // namespace vmsim::sim
