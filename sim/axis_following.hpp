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
#include <vector>

namespace vmsim::sim {

// The sum of a sequence of numbers in the order Eigen 3.4's vectorised reduction adds them (ArrayXd::sum(): lanes of
// SIMD packets, two packets at a time, then the lanes, then the scalar tail), so that a figure summed block by block
// equals the one the whole array gave, bit for bit. tests/sim/motion_stream_test.cpp compares it with Eigen.
class EigenOrderSum {
 public:
  void add(double v);
  double sum() const;  // 0 for no values
  Eigen::Index count() const { return n_; }

 private:
  static constexpr int kMaxLanes = 16;
  double r0_[kMaxLanes / 2] = {}, r1_[kMaxLanes / 2] = {};  // the two packet accumulators, once a group is complete
  double pending_[kMaxLanes] = {};                          // the values of the group being filled
  int pending_n_ = 0;
  Eigen::Index n_ = 0, groups_ = 0;
};

// The figures below taken block by block (a streamed motion, sim/motion_stream.hpp): add() the actual axis positions
// of rows [k0, k0 + rows) in order, then json(). Any split into blocks gives the same figures, bit for bit.
class AxisFollowing {
 public:
  // samples: the rows counted (the setpoints' samples, or fewer when the response is shorter). kin (may be null:
  // no "tool_axis") and tool_length_offset must outlive the object.
  AxisFollowing(const core::Machine& machine, Eigen::Index samples, const motion::Kinematics* kin,
                std::function<double(Eigen::Index)> tool_length_offset);
  void add(Eigen::Index k0, const core::Setpoints& setpoints, const Eigen::MatrixXd& actual_rows);
  // The same with the block's tool axes known (rows of the block, 3 columns: forward()'s axis of the setpoint and of
  // the actual row): add()'s figures bit for bit, the angle computed again only where the two axes change.
  // Throws core::Error when their shapes are not the block's.
  void add(Eigen::Index k0, const core::Setpoints& setpoints, const Eigen::MatrixXd& actual_rows,
           const Eigen::Ref<const Eigen::MatrixXd>& command_axis, const Eigen::Ref<const Eigen::MatrixXd>& actual_axis);
  nlohmann::json json(double period_s) const;

 private:
  void add_axes(Eigen::Index k0, const core::Setpoints& setpoints, const Eigen::MatrixXd& actual_rows);
  void add_tool_angle(const Eigen::Vector3d& command, const Eigen::Vector3d& actual);
  struct Axis {
    double max = 0;
    Eigen::Index at = 0;
    EigenOrderSum sum2;
  };
  const core::Machine* machine_;
  Eigen::Index n_;
  const motion::Kinematics* kin_;
  std::function<double(Eigen::Index)> tlo_;
  std::vector<Axis> axes_;
  double tool_max_ = 0, tool_ss_ = 0;
  // The last tool-axis pair and its angle (the tool axis of a three-axis program never turns).
  bool last_valid_ = false;
  Eigen::Vector3d last_command_, last_actual_;
  double last_angle_deg_ = 0;
};

// Per machine axis over the setpoint samples (row k of `actual` is the axis when setpoint k is sent): largest |e|
// (its first sample on a tie) and RMS of e = setpoint - actual, in mm (linear axes) or degrees (rotary axes, keys
// *_deg), and the sample time of the largest. With `kin`, also "tool_axis": the largest and RMS angle (degrees)
// between the tool axis of the commanded and of the actual axis positions, in the workpiece frame. AxisFollowing
// over one block.
nlohmann::json axis_following_json(const core::Machine& machine, const core::Setpoints& setpoints,
                                   const Eigen::MatrixXd& actual, const motion::Kinematics* kin,
                                   const std::function<double(Eigen::Index)>& tool_length_offset);

}  // namespace vmsim::sim
