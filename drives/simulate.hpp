#pragma once
// All axes of a job, from the interpolator's setpoints to the positions the machine really reaches.
#include "core/machine.hpp"
#include "core/setpoints.hpp"
#include "drives/axis_model.hpp"

#include <Eigen/Core>

#include <memory>
#include <string>
#include <vector>

namespace vmsim::drives {

// Per-sample gains (Duong et al.'s OGA): samples x axes; NaN keeps the drive's own value. Empty matrices: no schedule.
// During the settling rows the last row's gains stay in force.
struct GainSchedule {
  Eigen::MatrixXd kv_per_s, kf;
};

struct SimulateOptions {
  const GainSchedule* gains = nullptr;
  bool full_rate_trace = false;  // also keep every current-loop sample of every axis
  double settle_s = 0.2;         // keep simulating this long after the last setpoint (axes come to rest)
  // Per machine axis (machine-file order), a model to run instead of the cascade of [axes.drive]: a prototype that
  // is cloned and reset, e.g. an identified transfer function (drives/discrete_tf_axis). Null entries, or no vector:
  // the cascade. Such an axis has no currents (zero) and no full-rate trace.
  const std::vector<const AxisModel*>* axis_models = nullptr;
};

// Inner-loop samples of one axis at its current-loop period: sample n is at t = n * period_s (the state at the start
// of that current period, with the setpoint and voltage held over it); (rows - 1) * Te / period_s + 1 samples, so
// the last one is at the last row's instant. Empty for an axis without a drive (held, not simulated).
struct FullRateTrace {
  double period_s = 0.0;
  Eigen::ArrayXd position, velocity, current_A, current_setpoint_A, voltage_V;
};

struct AxisResponse {
  double period_s = 1e-3;               // Te
  std::vector<std::string> axis_names;  // machine axes, in the machine file's order
  // samples x axes, axis units (mm, rad): one row per setpoint, then the settling samples. Row k is the axis at
  // t = k Te, the instant setpoint k is sent (row 0: at rest at the first setpoint), so rows and setpoints share
  // their time base. Acceleration: mean over the period ending at row k; jerk: its backward difference.
  Eigen::MatrixXd position, velocity, acceleration, jerk, current_A, current_setpoint_A;
  Eigen::MatrixXd current_mean_A, current_peak_A;  // over each Te period (see AxisSample)
  std::vector<FullRateTrace> trace;                // per axis when full_rate_trace
  Eigen::Index samples() const { return position.rows(); }
};

// One axis on its own, as simulate_axes runs each: `model` already reset at setpoints[0]; returns `rows` positions
// (row k at t = k Te; beyond the last setpoint the NC holds it). The feedforward set points are the backward
// differences of the setpoints, as in simulate_axes.
Eigen::VectorXd simulate_axis(AxisModel& model, const Eigen::VectorXd& setpoints, double te, Eigen::Index rows);

// Cascade axes with the same loop periods are stepped together (drives/cascade_batch), bit for bit as
// CascadeAxis::step steps each alone. Throws core::Error naming the machine file when an axis the setpoints move has
// no [axes.drive].
AxisResponse simulate_axes(const core::Setpoints& setpoints, const core::Machine& machine,
                           const SimulateOptions& options = {});

// The same simulation in blocks of rows, so that a long program's response need not be held whole (issue 21): each
// next() returns the following rows (setpoint rows, then the settling rows) as an AxisResponse of those rows, every
// drive's state carried from one block to the next, so that the blocks put together are simulate_axes' response
// bit for bit. `setpoints` (and the gain schedule) must outlive the simulation. Throws as simulate_axes does, and
// for a full-rate trace (only simulate_axes keeps one).
class BlockSimulation {
 public:
  BlockSimulation(const core::Setpoints& setpoints, const core::Machine& machine, const SimulateOptions& options = {});
  ~BlockSimulation();
  BlockSimulation(BlockSimulation&&) noexcept;
  BlockSimulation& operator=(BlockSimulation&&) noexcept;

  Eigen::Index rows() const;      // all rows: setpoints, then settle_s / Te settling rows
  Eigen::Index next_row() const;  // the first row the next block holds
  bool done() const { return next_row() >= rows(); }
  // Rows [next_row(), next_row() + min(block_rows, rows() - next_row())). Throws for block_rows < 1.
  AxisResponse next(Eigen::Index block_rows);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace vmsim::drives
