// vmsim command line. CLI11 stays in this one translation unit (STACK.md P11: 9 s to compile).
#include "app/commands.hpp"
#include "app/commands_sysid.hpp"
#include "app/commands_oga.hpp"
#include "app/commands_study.hpp"
#include "app/mpi_session.hpp"
#include "core/error.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>

namespace {
int run_command(int argc, char** argv);
}  // namespace

// MPI (when launched by mpirun) wraps the whole command; an error on one rank ends all ranks (no hang).
int main(int argc, char** argv) {
  vmsim::app::mpi_start(&argc, &argv);
  const int code = run_command(argc, argv);
  if (code != 0) vmsim::app::mpi_abort_all(code);
  vmsim::app::mpi_finish();
  return code;
}

namespace {
int run_command(int argc, char** argv) {
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

  vmsim::app::IdentifyFrictionArgs id_args;
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

  vmsim::app::MotionArgs motion_args;
  auto* motion = app.add_subcommand(
      "motion", "Simulate the servo drives following the setpoints: actual positions, tracking and contour errors");
  motion->add_option("JOB", motion_args.job, "job file (job.toml)")->required()->check(CLI::ExistingFile);
  motion->add_option("--out,-o", motion_args.out_dir, "output directory (created if absent)");
  motion->add_option("--feed-scale", motion_args.feed_scale, "multiply every programmed feed (e.g. 0.5)")
      ->check(CLI::PositiveNumber);
  motion->add_flag("--full-rate-trace", motion_args.full_rate_trace,
                   "also write every current-loop sample of every axis (trace_<axis>.csv, large)");

  // Duong et al.: offline gain adjustment of a biaxial profile.
  vmsim::app::OgaArgs oga_args;
  auto* oga = app.add_subcommand(
      "oga", "Offline gain adjustment (Duong et al.): admissible gains per axis, the best fixed pair (C1), a position-gain "
             "schedule by receding windows (C2) for [job] gain_schedule, MSE(CE) C1 vs C2, limits, currents, charts");
  oga->add_option("JOB", oga_args.job, "job file of a biaxial profile (two of X Y Z move)")->required()->check(CLI::ExistingFile);
  oga->add_option("--out,-o", oga_args.out_dir, "output directory (created if absent)");
  oga->add_option("--kp-grid", oga_args.kp_grid, "Kv values swept, MIN:STEP:MAX in (m/min)/mm (default 1:0.5:9)");
  oga->add_option("--kf-grid", oga_args.kf_grid, "KF values swept, MIN:STEP:MAX (default 0:0.1:1.2)");
  oga->add_option("--range", oga_args.ranges,
                  "Kv range of the schedule, MIN:MAX for every axis or AXIS=MIN:MAX, repeatable (default: [Kv1 - 1, "
                  "Kv1 + 0.5] around C1 within the admissible Kv, as Duong et al.'s [5, 6.5] around 6)");
  oga->add_option("--dk", oga_args.gain_step, "gain step dK of the candidates, (m/min)/mm (default 0.03)");
  oga->add_option("--frequency-hz", oga_args.frequency_hz, "f of the gain function's sinusoid, eq. 3 (default 10: p = 50 at Te 1 ms)");
  oga->add_option("--reference", oga_args.reference, "C1: best (the best admissible fixed pair, default) or machine (the machine file's gains)")
      ->check(CLI::IsMember({"best", "machine"}));
  oga->add_option("--straight-curvature", oga_args.straight_curvature_per_mm,
                  "windows: |curvature| below this is straight, 1/mm (default 1e-4)");
  oga->add_option("--transition-rate", oga_args.transition_rate_per_mm2,
                  "windows: a transition where the curvature changes faster than this, 1/mm^2 (default 0.01)");
  oga->add_option("--min-window-rows", oga_args.min_window_rows, "windows: shorter runs join the one before (default 3)");
  oga->add_option("--lead-in-rows", oga_args.lead_in_rows, "rows before a window in its contour error (default 100)");
  oga->add_option("--settle-s", oga_args.settle_s, "simulated after the last setpoint, s (default 0.2)");
  oga->add_flag("--from-start", oga_args.from_start,
                "simulate every candidate from the first instant, as Duong et al. (same answer, slower)");
  oga->add_option("--threads", oga_args.threads, "OpenMP threads (default: all; the result does not depend on it)");
  oga->add_flag("--no-render", oga_args.no_render, "draw no charts (by default: PNG files in OUT/images)");
  oga->add_option("--image-size", oga_args.image_size, "size of the charts, WIDTHxHEIGHT (default 1600x900)");

  vmsim::app::RunArgs run_args;
  auto* run = app.add_subcommand(
      "run", "Run the whole chain: interpolator, drives, material removal; the machined surface and its marks");
  run->add_option("JOB", run_args.job, "job file (job.toml)")->required()->check(CLI::ExistingFile);
  run->add_option("--out,-o", run_args.out_dir, "output directory (created if absent)");
  run->add_option("--feed-scale", run_args.feed_scale, "multiply every programmed feed of this job")
      ->check(CLI::PositiveNumber);
  run->add_flag("--quiet,-q", run_args.quiet, "no progress on stderr");
  run->add_flag("--no-render", run_args.no_render, "draw no pictures (by default: PNG files in OUT/images)");
  run->add_option("--image-size", run_args.image_size, "size of the pictures, WIDTHxHEIGHT (default 1600x1200)");
  // Under mpirun -np N the stock is split into N tiles (app/tiled_run.hpp); results are gathered to rank 0.
  run->add_flag("--tiles-out", run_args.tiles_out,
                "under mpirun: each rank writes its tile (OUT/tiles/*.x3p) and rank 0 a manifest (OUT/tiles.json), "
                "instead of gathering the whole part to rank 0");
  run->add_flag("--plan", run_args.plan,
                "dry run: the memory the job needs (field, motion, sweeps, outputs) for one process and per rank, "
                "written to OUT/plan.json with --out");
  run->add_option("--ranks", run_args.ranks, "--plan: ranks of the tiled run (default: the MPI world size)")
      ->check(CLI::PositiveNumber);
  run->add_option("--memory-per-rank-gb", run_args.memory_per_rank_gb,
                  "--plan: memory per rank (GB) to advise how many ranks or which spacing the job needs")
      ->check(CLI::PositiveNumber);

  vmsim::app::StudyArgs study_args;
  auto* study = app.add_subcommand(
      "study", "Run a job's variations (feeds, gains, tolerances, machine keys) through vmsim run and write one table "
               "of their marks, contour errors and cycle times; under mpirun the variations are spread over the ranks");
  study->add_option("STUDY", study_args.study, "study file (parts/README.md: Study file)")
      ->required()->check(CLI::ExistingFile);
  study->add_option("--out,-o", study_args.out_dir, "output directory: results.csv, study.json, variations/NNN/")
      ->required();
  study->add_option("--keep", study_args.keep,
                    "each variation's files: all (default: vmsim run's outputs) or summary (job, machine, report.json, "
                    "run.log)")
      ->check(CLI::IsMember({"all", "summary"}));
  study->add_flag("--quiet,-q", study_args.quiet, "no line per finished variation");

  vmsim::app::RenderArgs render_args;
  auto* render = app.add_subcommand(
      "render", "Draw the pictures of a result directory of vmsim run or motion: the part under a raking light, "
                "its deviation maps, charts of the drive signals (PNG, no display needed)");
  render->add_option("DIR", render_args.dir, "result directory (surface.csv, deviation.csv, signals.csv, report.json)")
      ->required()->check(CLI::ExistingDirectory);
  render->add_option("--out,-o", render_args.out_dir, "where the PNG files go (default: DIR/images)");
  render->add_option("--size", render_args.images.size, "WIDTHxHEIGHT in pixels (default 1600x1200)");
  render->add_option("--exaggeration", render_args.images.exaggeration, "vertical exaggeration of the part pictures")
      ->check(CLI::PositiveNumber);
  render->add_option("--region", render_args.images.region,
                     "X_MIN,X_MAX,Y_MIN,Y_MAX (mm): zoom on this region instead of the deepest mark")
      ->delimiter(',')->expected(4);
  render->add_option("--limit-um", render_args.images.limit_um,
                     "colour limits of the deviation maps, +-um (default: max |deviation| rounded up)")
      ->check(CLI::PositiveNumber);
  render->add_option("--isolines", render_args.images.isolines, "iso-deviation lines per side of zero (default 3)")
      ->check(CLI::Range(0, 20));
  render->add_option("--magnification", render_args.images.magnification,
                     "of the mark's departure from the reference in part_mark.png (default: from its depth)")
      ->check(CLI::PositiveNumber);
  render->add_option("--path-direction-deg", render_args.images.path_direction_deg,
                     "cutting direction in the XY plane for the along-the-path views (default: the axis that travels "
                     "furthest)");


  // Surface commands (metrology): measured scans against predicted surfaces.
  vmsim::app::StatsArgs stats_args;
  auto* stats = app.add_subcommand(
      "stats", "Print a surface file's size, spacing, invalid points and ISO 25178-2 areal parameters as JSON (a "
               "profile: its ISO 21920-2 profile parameters)");
  stats->add_option("SURFACE", stats_args.surface,
                    "X3P, SDF, .sur, BCR-STM, CSV, ASCII x y z or matrix grid (also gzip-compressed), or a profile "
                    "(Dektak CSV, X3P PRF, .sur profile): its ISO 21920-2 profile parameters")
      ->required()->check(CLI::ExistingFile);
  stats->add_option("--level", stats_args.options.level, "form removed first: none, plane (default) or poly:N");
  stats->add_option("--filter", stats_args.options.filters,
                    "Gaussian filter (ISO 16610-61), repeatable: S:<cut-off> keeps the mean surface, L:<cut-off> "
                    "removes it (cut-offs with units, e.g. L:0.8mm, S:2.5um)");
  stats->add_option("--outliers", stats_args.options.outlier_sigma,
                    "mask spikes beyond this many robust sigmas first (default 0: keep every point)")
      ->check(CLI::NonNegativeNumber);
  stats->add_option("--range", stats_args.options.profile_range,
                    "profiles: X0,X1 (lengths, e.g. 468um,733um), the part of the trace evaluated: the samples nearest to X0 "
                    "and X1 and those between (default: all)");

  vmsim::app::CompareArgs compare_args;
  auto* compare = app.add_subcommand(
      "compare", "Hold a measured scan against a predicted surface: registration, deviation (X3P), marks, areal "
                 "parameters, report.json, pictures");
  compare->add_option("--measured,-m", compare_args.measured,
                      "the measured scan (X3P, SDF, .sur, BCR-STM, CSV, ASCII grids) or profile (Dektak CSV, X3P PRF)")
      ->required()->check(CLI::ExistingFile);
  compare->add_option("--predicted,-p", compare_args.predicted,
                      "the predicted surface (e.g. vmsim run's surface.x3p) or part mesh (.stl)")
      ->required()->check(CLI::ExistingFile);
  compare->add_option("--out,-o", compare_args.out_dir, "output directory (created if absent)");
  compare->add_option("--align", compare_args.align, "auto (robust 6-DoF registration, default) or none");
  compare->add_option("--align-init", compare_args.align_init,
                      "X,Y,Z,RX,RY,RZ (mm, deg): start of the registration, or with --align none the transform")
      ->delimiter(',')->expected(6);
  compare->add_option("--align-region", compare_args.align_regions,
                      "XMIN,XMAX,YMIN,YMAX (mm, prediction frame), repeatable: align only on these areas (the "
                      "unmachined reference faces)");
  compare->add_option("--loss", compare_args.loss, "robust loss of the registration: tukey (default) or huber");
  compare->add_option("--level", compare_args.options.level, "form removed before the areal parameters: none, plane, poly:N");
  compare->add_option("--filter", compare_args.options.filters, "Gaussian filter before the areal parameters: S:<cut-off>, L:<cut-off>");
  compare->add_option("--outliers", compare_args.options.outlier_sigma,
                      "mask spikes of the scan beyond this many robust sigmas (default 6; 0: keep every point)")
      ->check(CLI::NonNegativeNumber);
  compare->add_option("--mark-threshold", compare_args.mark_threshold, "marks: |deviation| above this (default 1um)");
  compare->add_option("--path-direction-deg", compare_args.path_direction_deg,
                      "the tool path's direction in XY for the marks' width and length (default: the prediction's lay)");
  compare->add_flag("--no-render", compare_args.no_render, "draw no pictures");
  compare->add_option("--profile-line", compare_args.profile_line,
                      "a measured profile: X0,Y0,X1,Y1 (mm, prediction frame), the line across the prediction it was "
                      "measured along");
  compare->add_option("--range", compare_args.options.profile_range,
                      "a measured profile: X0,X1 (lengths), the part of the trace compared (default: all)");

  vmsim::app::MeasureArgs measure_args;
  auto* measure = app.add_subcommand(
      "measure", "Simulate a confocal point sensor scanning a predicted surface, to plan a scan: what it resolves");
  measure->add_option("PRED", measure_args.predicted, "the predicted surface (e.g. vmsim run's surface.x3p)")
      ->required()->check(CLI::ExistingFile);
  measure->add_option("--step", measure_args.step, "scan grid step (default 5um)");
  measure->add_option("--spot", measure_args.spot, "spot diameter, full width at half maximum (default 4um)");
  measure->add_option("--noise", measure_args.noise, "height noise, standard deviation (default 0.05um)");
  measure->add_option("--max-slope-deg", measure_args.max_slope_deg, "steeper flanks give no signal (default 30)")
      ->check(CLI::Range(0.1, 90.0));
  measure->add_option("--dropout", measure_args.dropout, "probability of a random dropout per point (default 0)")
      ->check(CLI::Range(0.0, 0.99));
  measure->add_option("--seed", measure_args.seed, "seed of the noise and dropouts (default 1)");
  measure->add_option("--area", measure_args.area, "XMIN,XMAX,YMIN,YMAX (mm): the scanned area (default: all)")
      ->delimiter(',')->expected(4);
  measure->add_option("--reference", measure_args.reference,
                      "reference surface (e.g. vmsim run's reference.x3p): report which predicted marks the scan resolves")
      ->check(CLI::ExistingFile);
  measure->add_option("--mark-threshold", measure_args.mark_threshold, "marks: |deviation| above this (default 1um)");
  measure->add_option("--out,-o", measure_args.out_dir, "output directory (created if absent)");

  vmsim::app::PlanFeedArgs plan_feed_args;
  auto* plan_feed = app.add_subcommand(
      "plan-feed", "Plan the feed along a job's path so the servo's contour error stays within a tolerance (seed "
                   "003: a linear program on the squared feed), play it through the interpolator and the drives");
  plan_feed->add_option("JOB", plan_feed_args.job, "job file with a [feedplan] table")->required()->check(CLI::ExistingFile);
  plan_feed->add_option("--out,-o", plan_feed_args.out_dir, "output directory (created if absent)");
  plan_feed->add_flag("--no-render", plan_feed_args.no_render, "draw no charts (by default: PNG files in OUT/images)");

  // The predictive-compensation paper: identification signals, transfer-function identification, predictive compensation.
  vmsim::app::ExciteArgs excite_args;
  auto* excite = app.add_subcommand(
      "excite", "Write the predictive-compensation paper's identification signal for one axis (inverse M-sequence or PRBS, eq. 8-15) as a "
                "G-code program or a setpoint CSV; --simulate also writes the trace the machine file's drive gives");
  excite->add_option("AXIS", excite_args.axis, "axis name (X Y Z A B C)")->required();
  excite->add_option("--machine,-m", excite_args.machine, "machine file")->required()->check(CLI::ExistingFile);
  excite->add_option("--out,-o", excite_args.out, "output: .ngc (G-code) or .csv (t_s and the setpoint every Te)")->required();
  excite->add_option("--signal", excite_args.signal, "inverse-m (default: no DC, the predictive-compensation paper) or prbs");
  excite->add_option("--bits", excite_args.bits, "shift-register length n, 2..20 (default: from --resolution-hz)");
  excite->add_option("--resolution-hz", excite_args.resolution_hz, "lowest frequency resolved, 1 / signal period (default 1)");
  excite->add_option("--bandwidth-hz", excite_args.bandwidth_hz,
                     "axis bandwidth the signal covers: Td = q Te with 0.433 / Td >= B (default 100, the predictive-compensation paper)");
  excite->add_option("--td-ms", excite_args.td_ms, "minimum switching interval Td in ms (overrides --bandwidth-hz)");
  excite->add_option("--amplitude", excite_args.amplitude, "a: +-a about the ramp, mm or deg (default 0.05)");
  excite->add_option("--feed", excite_args.feed,
                     "constant velocity the signal rides on, mm/min or deg/min, so the axis never reverses and Coulomb "
                     "friction stays constant (default 1200; 0: about a fixed point)");
  excite->add_option("--periods", excite_args.periods, "signal periods (default 4: identify on 2, validate on 2)");
  excite->add_option("--start", excite_args.start, "start position, mm or deg (default: centred in the travel)");
  excite->add_option("--period-ms", excite_args.period_ms, "sampling period Te in ms (default 1)");
  excite->add_option("--simulate", excite_args.simulate,
                     "also run the setpoints through the axis's [axes.drive] and write this position trace CSV");

  vmsim::app::IdentifyArgs sysid_args;
  auto* sysid = app.add_subcommand(
      "identify", "Identify each axis as a discrete transfer function from a position trace (ARX, ARMAX, OE; the predictive-compensation paper), "
                  "validate, rank, and write axis_models.toml for jobs to run on");
  sysid->add_option("--trace,-t", sysid_args.traces,
                    "position trace CSV: t_s, <AXIS>_command_mm, <AXIS>_actual_mm, ... (vmsim motion's trace.csv); repeat it for "
                    "several experiments, identified together")
      ->required();
  sysid->add_option("--validate", sysid_args.validate, "a separate validation trace (default: one trace's second half, or "
                    "with several traces the last one)");
  sysid->add_option("--axis", sysid_args.axes, "axes to identify, repeatable (default: every axis in the trace)");
  sysid->add_option("--structure,-s", sysid_args.structure, "arx, armax, oe or all (default)");
  sysid->add_option("--orders", sysid_args.orders, "NB,NA: numerator and denominator orders (default 2,5) or auto (BIC)");
  sysid->add_option("--nc", sysid_args.nc, "ARMAX noise numerator order (default 2)");
  sysid->add_option("--delay", sysid_args.delay, "input delay nk in samples, or auto (default)");
  sysid->add_option("--use", sysid_args.use, "structure written to the model file: best (lowest validation MSE, default), arx, armax or oe");
  sysid->add_option("--out,-o", sysid_args.out_dir, "output directory for axis_models.toml and report.json");

  vmsim::app::CompensateArgs comp_args;
  auto* compensate = app.add_subcommand(
      "compensate", "Predict a job's contour error and add it back to the setpoints (the predictive-compensation paper): compensated setpoints, "
                    "a compensated G-code program, contour error before and after");
  compensate->add_option("JOB", comp_args.job, "job file (job.toml)")->required()->check(CLI::ExistingFile);
  compensate->add_option("--out,-o", comp_args.out_dir, "output directory (created if absent)");
  compensate->add_option("--axis-models", comp_args.axis_models,
                         "predict with these identified models (default: the job's [job] axis_models, else the machine's cascades)");
  compensate->add_option("--buffer", comp_args.buffer_samples, "foot-point search buffer m, odd (default 0: automatic)");
  compensate->add_option("--iterations", comp_args.max_iterations, "largest number of corrections (default 6)");
  compensate->add_option("--smoothing", comp_args.smoothing_samples,
                         "standard deviation of the correction's Gaussian smoothing along the setpoints, in samples (default 4)");
  compensate->add_flag("--no-render", comp_args.no_render, "draw no chart (by default: OUT/images/contour_error.png)");
  compensate->add_flag("--tip-only", comp_args.tip_only,
                       "five-axis machines: correct the tool tip only (default: the tool axis' orientation error too)");
  compensate->add_flag("--dense-program", comp_args.dense_program,
                       "also write compensated_dense.ngc: the compensated setpoints as one G93 block per period Te");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }

  try {
    if (*canon) return vmsim::app::run_canon(program, tool_table, no_motion_mcodes);
    if (*interp) return vmsim::app::run_interp(interp_args);
    if (*identify) return vmsim::app::run_identify_friction(id_args);
    if (*motion) return vmsim::app::run_motion(motion_args);
    if (*oga) return vmsim::app::run_oga(oga_args);
    if (*excite) return vmsim::app::run_excite(excite_args);
    if (*sysid) return vmsim::app::run_identify(sysid_args);
    if (*compensate) return vmsim::app::run_compensate(comp_args);
    if (*run) return vmsim::app::run_run(run_args);
    if (*study) return vmsim::app::run_study(study_args);
    if (*render) return vmsim::app::run_render(render_args);
    if (*stats) return vmsim::app::run_stats(stats_args);
    if (*compare) return vmsim::app::run_compare(compare_args);
    if (*measure) return vmsim::app::run_measure(measure_args);
    if (*plan_feed) return vmsim::app::run_plan_feed(plan_feed_args);
  } catch (const vmsim::core::Error& e) {
    std::fprintf(stderr, "vmsim: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vmsim: internal error: %s\n", e.what());
    return 3;
  }
  return 0;
}
}  // namespace
