#pragma once
// Gain schedules as files (Duong et al.'s variable gains): `vmsim oga` writes them, `vmsim run` and `vmsim motion`
// apply one through the job's `gain_schedule` key (parts/README.md).
//
// Format (CSV, '#' lines first):
//   # vmsim gain schedule 1: position-loop gains per setpoint row (Duong et al. OGA); Kv in (m/min)/mm, KF
//   dimensionless # job=NAME                 the job it was computed for (information) # period_s=0.001           Te of
//   the setpoints (checked) # samples=4264             setpoint rows (checked) # ...                      free comment
//   lines row,t_s,X_setpoint_mm,X_kv_1000_per_min,X_kf,Z_setpoint_mm,Z_kv_1000_per_min,Z_kf one line per setpoint row k
//   = 0, 1, ...: t = k Te, each scheduled axis' setpoint (mm, or deg for a rotary axis; checked against the job's own
//   within 1e-6, so that a schedule is never applied to another path) and its gains; "nan" or an empty cell keeps the
//   drive's own gain (the machine file's kv_1000_per_min or kf).
// Axes not in the file keep their drive's gains. While the axes settle after the last setpoint, the last row's
// gains stay in force (drives::simulate_axes).
#include "core/machine.hpp"
#include "core/setpoints.hpp"
#include "drives/simulate.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <string>
#include <vector>

namespace vmsim::methods {

// A schedule in the file's units.
struct GainTable {
  std::vector<std::string> axis_names;  // machine axes the schedule sets
  Eigen::MatrixXd kv_1000_per_min, kf;  // setpoint rows x axis_names; NaN: the drive's own
};

// kv in 1/s (kv_1000_per_min x 1000/60, as the machine file's), a column per machine axis, NaN elsewhere. Throws
// core::Error for an axis the machine does not have.
drives::GainSchedule to_gain_schedule(const GainTable& table, const core::Machine& machine);

// Written atomically; gains with 17 significant digits, so that reading the file back gives the same schedule bit
// for bit. `setpoints`: the job's, for the t_s and setpoint columns. `comments`: extra '#' lines.
void write_gain_schedule(const std::filesystem::path& file, const GainTable& table, const core::Setpoints& setpoints,
                         const core::Machine& machine, const std::string& job_name,
                         const std::vector<std::string>& comments = {});

// Reads a schedule and checks it against the setpoints it is to be applied to (rows, Te, every setpoint).
// Throws core::Error naming the file, the line and what was expected.
GainTable read_gain_table(const std::filesystem::path& file, const core::Setpoints& setpoints,
                          const core::Machine& machine);
inline drives::GainSchedule read_gain_schedule(const std::filesystem::path& file, const core::Setpoints& setpoints,
                                               const core::Machine& machine) {
  return to_gain_schedule(read_gain_table(file, setpoints, machine), machine);
}

}  // namespace vmsim::methods
