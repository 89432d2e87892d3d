#pragma once
// The checks of a run's drives, before and after they run (issue 18: nothing silently wrong). Before: each cascade
// the setpoints move, through its linearised model (drives/drive_checks: stability, gain margin, damping). After:
// the time each axis spends with its current setpoint at the drive's limit, and its following error against the
// error its own linear model predicts for the setpoints' velocity and acceleration. report.json holds the findings
// ("warnings") and the verdict; the CLI prints them and exits with kExitInvalid for "invalid".
#include "core/machine.hpp"
#include "core/setpoints.hpp"
#include "core/warning.hpp"
#include "drives/simulate.hpp"

#include <nlohmann/json.hpp>

#include <vector>

namespace vmsim::sim {

// The exit code of a command whose result is "invalid" (README, "What you can rely on"): the files and report.json
// are written, but the result cannot mean what it claims. Errors exit with 2, internal errors with 3.
inline constexpr int kExitInvalid = 4;

// A run's findings and each checked axis's figures.
struct DriveChecks {
  core::Warnings warnings;
  nlohmann::json axes = nlohmann::json::object();  // per axis: kv_te, pole_radius, gain_margin, min_damping, ...
};

// Before the drives run: the cascades of the axes in `cascade` (per machine axis: runs the machine's cascade) that
// the setpoints move. Throws core::Error, naming the machine file, the axis and the keys, for an unstable loop:
// nothing the simulation gives could mean anything.
DriveChecks check_drives_before(const core::Machine& machine, const core::Setpoints& setpoints,
                                const std::vector<bool>& cascade);

// After: adds each checked axis's saturation time and following error to `checks`, and the findings:
// current_saturation (the setpoint at the current limit for 10 ms or more in one stretch), following_error_beyond_model
// (over the linear model's bound: 3 (|c1| v_max + |c2| a_max) plus 10 um, or 1e-4 rad on a rotary axis) and,
// Invalid, following_error_implausible (over 10 times that bound). `gains`: the run's gain schedule, whose lowest
// Kv and KF the bound takes.
void check_drives_after(const core::Machine& machine, const core::Setpoints& setpoints,
                        const drives::AxisResponse& response, const std::vector<bool>& cascade,
                        const drives::GainSchedule* gains, DriveChecks& checks);

// The largest |x_k - x_k-1| (k >= 1) and |x_k - 2 x_k-1 + x_k-2| (k >= 2) of x[0, n), bit for bit as std::max folds
// them in order from 0 (a NaN difference is skipped): the setpoints' largest velocity and acceleration steps.
void largest_setpoint_differences(const double* x, Eigen::Index n, double& d1_max, double& d2_max);

// The same checks after the run, fed the response in blocks of rows (issue 21: a long program's response is not held
// whole). The setpoints' positions must stay alive until the last add(). add(0, whole response) then finish() is
// check_drives_after.
class DriveChecksAfter {
 public:
  DriveChecksAfter(const core::Machine& machine, const core::Setpoints& setpoints, const std::vector<bool>& cascade,
                   const drives::GainSchedule* gains);
  // Response rows [k0, k0 + block.samples()), in order.
  void add(Eigen::Index k0, const core::Setpoints& setpoints, const drives::AxisResponse& block);
  void finish(DriveChecks& checks) const;

 private:
  struct Axis {
    std::size_t index = 0;
    core::DriveParams params;
    double bound = 0, v_max = 0, a_max = 0;
    double e_max = 0, e_row = 0, saturated = 0, longest = 0, run = 0;
  };
  const core::Machine* machine_;
  double te_;
  Eigen::Index ns_;
  std::vector<Axis> axes_;
};

// report.json's "warnings" (code, severity, subject, message each) and "verdict" (core::verdict).
nlohmann::json warnings_json(const core::Warnings& warnings);
void add_verdict(nlohmann::json& report, const core::Warnings& warnings);

}  // namespace vmsim::sim
