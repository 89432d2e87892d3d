#pragma once
// An axis drive as the simulation sees it: the NC sends it a setpoint every Te, it answers with where the axis
// really is. A real family: the cascade of the feed-drive simulation paper (drives/cascade_axis) and, later, the
// identified discrete transfer function of the predictive-compensation paper.
#include <limits>
#include <memory>

namespace vmsim::drives {

// What the NC sends one axis drive every Te (axis units: mm or rad).
struct AxisCommand {
  double position = 0.0;      // x_d, the position setpoint
  double velocity = 0.0;      // v_d for the velocity feedforward (backward difference of the setpoints)
  double acceleration = 0.0;  // a_d for the torque feedforward
  // Gain schedule (Duong et al.'s OGA): this sample's Kv (1/s) and KF; NaN keeps the drive's own value.
  double kv_per_s = std::numeric_limits<double>::quiet_NaN();
  double kf = std::numeric_limits<double>::quiet_NaN();
};

// The axis at the end of one Te period (load side, axis units).
struct AxisSample {
  double position = 0.0, velocity = 0.0, acceleration = 0.0;
  double current_A = 0.0;  // motor (torque-producing) current at the end of the period
  // Over the period's current-loop samples: the mean (what a drive trace averaged per Te shows; the end value is
  // biased while the axis accelerates, as the velocity command steps once per Te) and the largest |current|.
  double current_mean_A = 0.0, current_peak_A = 0.0;
  double current_setpoint_A = 0.0;  // velocity-loop output after saturation
};

class AxisModel {
 public:
  virtual ~AxisModel() = default;
  // At rest at `position` (axis units), holding its load: the state a drive settles to before the program starts.
  virtual void reset(double position) = 0;
  // Advances one position-loop period.
  virtual AxisSample step(const AxisCommand& command) = 0;
  // A full copy of the state: OGA evaluates its candidates from the drive state at a window start.
  virtual std::unique_ptr<AxisModel> clone() const = 0;
};

}  // namespace vmsim::drives
