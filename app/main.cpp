// vmsim command line. CLI11 stays in this one translation unit (STACK.md P11: 9 s to compile).
#include "app/commands.hpp"
#include "core/error.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>

int main(int argc, char** argv) {
  CLI::App app{
      "vmsim - virtual machining: predicts the surface a CNC milling machine really cuts, from the program\n"
      "through the NC interpolator, the servo drives and the kinematics to material removal and metrology."};
  app.set_version_flag("--version", std::string("vmsim ") + VMSIM_VERSION);
  app.require_subcommand(1);
  app.fallthrough(false);

  std::filesystem::path program;
  std::optional<std::filesystem::path> tool_table;
  auto* canon = app.add_subcommand(
      "canon", "Print LinuxCNC's canonical machining calls for a G-code program (compare with `rs274 -g`)");
  canon->add_option("PROGRAM", program, "G-code program (.ngc)")->required()->check(CLI::ExistingFile);
  canon->add_option("--tool-table,-t", tool_table, "LinuxCNC tool table (T1 P1 Z0 D10 lines)")
      ->check(CLI::ExistingFile);
  std::vector<int> no_motion_mcodes;
  canon->add_option("--no-motion-m", no_motion_mcodes,
                    "comma-separated M codes the machine remaps to actions without motion (e.g. 428,429)")
      ->delimiter(',');

  vmsim::app::InterpArgs interp_args;
  auto* interp = app.add_subcommand(
      "interp", "Interpolate a job's program into axis setpoints every Te (jerk-limited, within tolerance)");
  interp->add_option("JOB", interp_args.job, "job file (job.toml)")->required()->check(CLI::ExistingFile);
  interp->add_option("--out,-o", interp_args.out_dir, "output directory for setpoints.csv (created if absent)");
  interp->add_option("--feed-scale", interp_args.feed_scale, "multiply every programmed feed (e.g. 0.5)")
      ->check(CLI::PositiveNumber);
  interp->add_flag("--summary-only", interp_args.summary_only,
                   "print the cycle time and the axis peaks, write no setpoints.csv");

  vmsim::app::IdentifyArgs id_args;
  auto* identify = app.add_subcommand(
      "identify-friction", "Identify an axis' friction law and inertia from a trace of time, position or velocity, current");
  identify->add_option("TRACE", id_args.trace, "CSV: t_s, current_A, position_mm|position_deg|velocity_mm_per_s|velocity_deg_per_s")
      ->required()->check(CLI::ExistingFile);
  identify->add_option("--torque-constant", id_args.torque_constant_Nm_per_A, "motor torque constant Kt (N m/A)")
      ->check(CLI::PositiveNumber);
  identify->add_option("--lead-mm", id_args.lead_mm, "screw lead of a linear axis (mm per motor revolution)")
      ->check(CLI::PositiveNumber)
      ->excludes(identify->add_option("--gear-deg-per-rev", id_args.gear_deg_per_rev,
                                      "gear of a rotary axis (deg per motor revolution)")->check(CLI::PositiveNumber));
  identify->add_option("--machine", id_args.machine, "machine file giving Kt, lead or gear and gravity of --axis")
      ->check(CLI::ExistingFile)
      ->needs(identify->add_option("--axis", id_args.axis, "axis name in the machine file (X Y Z A B C)"));
  identify->add_option("--gravity", id_args.gravity, "gravity model: auto (default), none, constant, tilting")
      ->check(CLI::IsMember({"auto", "none", "constant", "tilting"}));
  identify->add_option("--smoothing-ms", id_args.smoothing_ms, "differentiation window (default 10 ms)")
      ->check(CLI::PositiveNumber);
  identify->add_option("--out,-o", id_args.out_dir, "write drive_identified.toml, friction_fit.csv, report.json here");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }

  try {
    if (*canon) return vmsim::app::run_canon(program, tool_table, no_motion_mcodes);
    if (*interp) return vmsim::app::run_interp(interp_args);
    if (*identify) return vmsim::app::run_identify_friction(id_args);
  } catch (const vmsim::core::Error& e) {
    std::fprintf(stderr, "vmsim: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vmsim: internal error: %s\n", e.what());
    return 3;
  }
  return 0;
}
