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
  bool no_render = false;                        // no pictures in DIR/images
  std::string image_size = "1600x1200";          // WIDTHxHEIGHT of the pictures
};
// vmsim run JOB: the whole chain to the machined surface and its marks; report.json, height grids, part mesh,
// signals.csv, and the pictures in DIR/images (app/result_images).
int run_run(const RunArgs& args);

// Picture options shared by vmsim render (and the defaults vmsim run uses).
struct ImageArgs {
  std::string size = "1600x1200";                // WIDTHxHEIGHT
  double exaggeration = 1.0;                     // vertical exaggeration of the part pictures
  std::vector<double> region;                    // X_MIN,X_MAX,Y_MIN,Y_MAX (mm): the zoom pictures' region
  std::optional<double> limit_um;                // colour limits of the deviation maps (default: max |deviation|)
  int isolines = 3;                              // iso-deviation lines per side of zero
  std::optional<double> magnification;           // of the mark's relief in part_mark.png (default: from its depth)
  std::optional<double> path_direction_deg;      // cutting direction in XY for the along-the-path views
};
struct RenderArgs {
  std::filesystem::path dir;                     // a result directory of vmsim run or vmsim motion
  std::optional<std::filesystem::path> out_dir;  // default: DIR/images
  ImageArgs images;
};
// vmsim render DIR: the part, deviation and chart pictures of a result directory (PNG), their paths on stdout.
int run_render(const RenderArgs& args);

}  // namespace vmsim::app
