#pragma once
// The vmsim subcommands. main.cpp parses the command line (CLI11) and calls these; each returns the
// process exit code and throws core::Error for input a user must fix.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::app {

// vmsim canon PROGRAM [--tool-table F] [--no-motion-m LIST]: LinuxCNC's canonical calls on stdout (as `rs274 -g`).
// no_motion_mcodes: M codes the machine remaps to actions without motion (GcodeOptions::no_motion_mcodes).
int run_canon(const std::filesystem::path& program, const std::optional<std::filesystem::path>& tool_table,
              const std::vector<int>& no_motion_mcodes = {});

struct InterpArgs {
  std::filesystem::path job;
  std::optional<std::filesystem::path> out_dir;  // default: the current directory
  std::optional<double> feed_scale;              // multiplies every programmed feed (override, as on the NC panel)
  bool summary_only = false;                     // print the summary, write no file
};
// vmsim interp JOB: setpoints.csv (t, each axis, path speed) and the cycle time.
int run_interp(const InterpArgs& args);

struct IdentifyArgs {
  std::filesystem::path trace;                   // CSV: t_s, current_A, position_mm|position_deg|velocity_...
  std::optional<double> torque_constant_Nm_per_A;
  std::optional<double> lead_mm, gear_deg_per_rev;
  std::optional<std::filesystem::path> machine;  // with axis: Kt, lead or gear, gravity model from the machine file
  std::optional<std::string> axis;
  std::string gravity = "auto";                  // auto | none | constant | tilting
  std::optional<double> smoothing_ms;            // IdentifyOptions::smoothing_s, in ms
  std::optional<std::filesystem::path> out_dir;  // drive_identified.toml, friction_fit.csv, report.json
};
// vmsim identify-friction TRACE: Coulomb and viscous friction, gravity offset and inertia of one axis (seed 004 3.1).
int run_identify_friction(const IdentifyArgs& args);

struct MotionArgs {
  std::filesystem::path job;
  std::optional<std::filesystem::path> out_dir;  // default: the current directory
  std::optional<double> feed_scale;
  bool full_rate_trace = false;                  // also write every current-loop sample (large)
};
// vmsim motion JOB: setpoints through the servo drives; actual positions, tracking and contour errors, currents
// (CSV), report.json.
int run_motion(const MotionArgs& args);

struct RunArgs {
  std::filesystem::path job;
  std::optional<std::filesystem::path> out_dir;  // default: the current directory
  std::optional<double> feed_scale;
  bool quiet = false;                            // no progress on stderr
};
// vmsim run JOB: the whole chain to the machined surface and its marks; report.json, height grids, part mesh.
int run_run(const RunArgs& args);

}  // namespace vmsim::app
