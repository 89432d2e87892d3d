#pragma once
// A job's motion as a library call (`vmsim motion`, the Python module's job.simulate()): the program through the
// job's chain (interpolator, drives), the tool tip commanded and actual, the contour error, and the figures of each
// axis against its limits.
#include "core/job.hpp"
#include "core/progress.hpp"
#include "core/toolpath.hpp"
#include "drives/simulate.hpp"
#include "motion/contour.hpp"
#include "motion/interp.hpp"
#include "sim/chain.hpp"
#include "sim/drive_checks.hpp"
#include "sysid/position_trace.hpp"

#include <nlohmann/json.hpp>

namespace vmsim::sim {

struct MotionRunOptions {
  double feed_scale = 1.0;
  bool full_rate_trace = false;  // also every current-loop sample of every axis (drives::AxisResponse::trace)
};

struct MotionRun {
  core::ToolPath program;         // as read (workpiece frame)
  motion::InterpResult interp;    // the setpoints
  drives::AxisResponse response;  // the drives' actual motion (setpoint rows, then the settling rows)
  motion::ContourError contour;   // the actual tool tip against the commanded one, per response row
  bool setpoint_limits_held = true, currents_within_limit = true;  // currents: never saturated at the limit
  DriveChecks drive_checks;  // the drives' findings (sim/drive_checks.hpp), also report.json's warnings
  // report.json's figures: interpolation, axes (tracking error, currents, setpoint and actual peaks, limits, in
  // each axis's file units), gain_schedule, axis_models, contour_error, limits_held, timings_s.
  nlohmann::json report;
};

// Throws core::Error naming the job file and key when the chain cannot run.
MotionRun run_motion(const core::Job& job, const MotionRunOptions& options = {},
                     core::Progress& progress = core::no_progress());

// Command and encoder position of every axis the program moves, as an NC's trace of the same run would give them
// (what `vmsim identify` reads).
sysid::PositionTrace position_trace(const core::Machine& machine, const core::Setpoints& setpoints,
                                    const drives::AxisResponse& response);

// An axis's positions in the units its files use (mm, or deg for a rotary axis), and the unit's name.
double file_unit(const core::MachineAxis& axis);
const char* unit_name(const core::MachineAxis& axis);

}  // namespace vmsim::sim
