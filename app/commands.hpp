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

}  // namespace vmsim::app
