// vmsim command line. CLI11 stays in this one translation unit (STACK.md P11: 9 s to compile). Each subcommand's
// options are declared in its own function below; options several commands share (--out, --feed-scale,
// --no-render, --image-size, the surface processing) are declared once, in the add_* helpers.
#include "app/commands.hpp"
#include "app/commands_oga.hpp"
#include "app/commands_study.hpp"
#include "app/commands_sysid.hpp"
#include "app/mpi_session.hpp"
#include "core/error.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <functional>
#include <iostream>
#include <memory>
#include <vector>

namespace {

namespace app = vmsim::app;
using Path = std::filesystem::path;

// ---- options several commands share ----

void add_out(CLI::App* c, std::optional<Path>& out,
             const std::string& what =
                 "result directory, replaced whole at the end (new, empty or an earlier vmsim result; default: "
                 "NAME_COMMAND/ here)") {
  c->add_option("--out,-o", out, what);
}
void add_feed_scale(CLI::App* c, std::optional<double>& scale,
                    const std::string& what = "multiply every programmed feed (e.g. 0.5)") {
  c->add_option("--feed-scale", scale, what)->check(CLI::PositiveNumber);
}
void add_no_render(CLI::App* c, bool& flag, const std::string& what) { c->add_flag("--no-render", flag, what); }
void add_image_size(CLI::App* c, std::string& size, const std::string& what) {
  c->add_option("--image-size", size, what);
}
// Under mpirun: how long a rank waits for the others at an exchange before the job is ended naming the ranks that did
// not arrive (app/tiled_run.hpp); wins over VMSIM_WATCHDOG_S.
void add_watchdog(CLI::App* c) {
  c->add_option_function<double>(
       "--watchdog-s", [](const double& s) { app::set_watchdog_seconds(s); },
       "under mpirun: end the job when a rank has not reached an exchange within this many seconds (default: "
       "VMSIM_WATCHDOG_S, else 3600)")
      ->check(CLI::PositiveNumber);
}
void add_job(CLI::App* c, Path& job, const std::string& what = "job file (job.toml)") {
  c->add_option("JOB", job, what)->required()->check(CLI::ExistingFile);
}
// Form removal, filters, spikes and a profile's range before the parameters (stats, compare).
void add_surface_options(CLI::App* c, app::SurfaceOptions& o, bool compare) {
  c->add_option("--level", o.level,
                compare ? "form removed before the areal parameters: none, plane, poly:N"
                        : "form removed first: none, plane (default) or poly:N");
  c->add_option("--filter", o.filters,
                compare ? "Gaussian filter before the areal parameters: S:<cut-off>, L:<cut-off>"
                        : "Gaussian filter (ISO 16610-61), repeatable: S:<cut-off> keeps the mean surface, L:<cut-off> "
                          "removes it (cut-offs with units, e.g. L:0.8mm, S:2.5um)");
  c->add_option("--outliers", o.outlier_sigma,
                compare ? "mask spikes of the scan beyond this many robust sigmas (default 6; 0: keep every point)"
                        : "mask spikes beyond this many robust sigmas first (default 0: keep every point)")
      ->check(CLI::NonNegativeNumber);
  c->add_option("--range", o.profile_range,
                compare ? "a measured profile: X0,X1 (lengths), the part of the trace compared (default: all)"
                        : "profiles: X0,X1 (lengths, e.g. 468um,733um), the part of the trace evaluated: the samples "
                          "nearest to X0 and X1 and those between (default: all)");
}

// A subcommand and what runs when it was given.
struct Command {
  CLI::App* sub = nullptr;
  std::function<int()> run;
};
using Commands = std::vector<Command>;

// ---- the subcommands, in the order of the chain ----

void add_canon(CLI::App& cli, Commands& cmds) {
  auto a = std::make_shared<app::CanonArgs>();
  auto* c = cli.add_subcommand("canon",
                               "Print LinuxCNC's canonical machining calls for a G-code (compare with `rs274 -g`) or "
                               "Sinumerik 840D program");
  c->add_option("PROGRAM", a->program, "program (.ngc .nc .txt G-code, .mpf .spf Sinumerik)")
      ->required()
      ->check(CLI::ExistingFile);
  c->add_option("--tool-table,-t", a->tool_table, "LinuxCNC tool table (T1 P1 Z0 D10 lines)")->check(CLI::ExistingFile);
  c->add_option("--no-motion-m", a->no_motion_mcodes,
                "comma-separated M codes the machine remaps to actions without motion (e.g. 428,429)")
      ->delimiter(',');
  c->add_option("--dialect", a->dialect, "the program's language: auto (by extension and content), rs274ngc, sinumerik")
      ->check(CLI::IsMember({"auto", "rs274ngc", "sinumerik"}));
  c->add_flag("--lenient", a->lenient,
              "Sinumerik: accept statements known to have no motion that vmsim does not model (unknown M and H "
              "functions, ...) with a warning instead of an error");
  cmds.push_back({c, [a] { return app::run_canon(*a); }});
}

void add_interp(CLI::App& cli, Commands& cmds) {
  auto a = std::make_shared<app::InterpArgs>();
  auto* c = cli.add_subcommand(
      "interp", "Interpolate a job's program into axis setpoints every Te (jerk-limited, within tolerance)");
  add_job(c, a->job);
  add_out(c, a->out_dir, "result directory for setpoints.csv (default: NAME_interp/ here)");
  add_feed_scale(c, a->feed_scale);
  c->add_flag("--summary-only", a->summary_only, "print the cycle time and the axis peaks, write no setpoints.csv");
  cmds.push_back({c, [a] { return app::run_interp(*a); }});
}

void add_motion(CLI::App& cli, Commands& cmds) {
  auto a = std::make_shared<app::MotionArgs>();
  auto* c = cli.add_subcommand(
      "motion", "Simulate the servo drives following the setpoints: actual positions, tracking and contour errors");
  add_job(c, a->job);
  add_out(c, a->out_dir);
  add_feed_scale(c, a->feed_scale);
  c->add_flag("--full-rate-trace", a->full_rate_trace,
              "also write every current-loop sample of every axis (trace_<axis>.csv, large)");
  cmds.push_back({c, [a] { return app::run_motion(*a); }});
}

void add_run(CLI::App& cli, Commands& cmds) {
  auto a = std::make_shared<app::RunArgs>();
  auto* c = cli.add_subcommand(
      "run", "Run the whole chain: interpolator, drives, material removal; the machined surface and its marks");
  add_job(c, a->job);
  add_out(c, a->out_dir);
  add_feed_scale(c, a->feed_scale, "multiply every programmed feed of this job");
  c->add_flag("--quiet,-q", a->quiet, "no progress on stderr");
  add_no_render(c, a->no_render, "draw no pictures (by default: PNG files in OUT/images)");
  add_image_size(c, a->image_size, "size of the pictures, WIDTHxHEIGHT (default 1600x1200)");
  // Under mpirun -np N the stock is split into N tiles (app/tiled_run.hpp); results are gathered to rank 0.
  c->add_flag("--tiles-out", a->tiles_out,
              "under mpirun: each rank writes its tile (OUT/tiles/*.x3p) and rank 0 a manifest (OUT/tiles.json), "
              "instead of gathering the whole part to rank 0");
  c->add_flag("--plan", a->plan,
              "dry run: the memory the job needs (field, motion, sweeps, outputs) for one process and per rank, "
              "written to OUT/plan.json with --out");
  c->add_option("--ranks", a->ranks, "--plan: ranks of the tiled run (default: the MPI world size)")
      ->check(CLI::PositiveNumber);
  c->add_option("--memory-per-rank-gb", a->memory_per_rank_gb,
                "--plan: memory per rank (GB) to advise how many ranks or which spacing the job needs")
      ->check(CLI::PositiveNumber);
  add_watchdog(c);
  cmds.push_back({c, [a] { return app::run_run(*a); }});
}

void add_study(CLI::App& cli, Commands& cmds) {
  auto a = std::make_shared<app::StudyArgs>();
  auto* c = cli.add_subcommand(
      "study",
      "Run a job's variations (feeds, gains, tolerances, machine keys) through vmsim run and write one table "
      "of their marks, contour errors and cycle times; under mpirun the variations are spread over the ranks");
  c->add_option("STUDY", a->study, "study file (parts/README.md: Study file)")->required()->check(CLI::ExistingFile);
  c->add_option("--out,-o", a->out_dir, "output directory: results.csv, study.json, variations/NNN/")->required();
  c->add_option("--keep", a->keep,
                "each variation's files: all (default: vmsim run's outputs) or summary (job, machine, report.json, "
                "run.log)")
      ->check(CLI::IsMember({"all", "summary"}));
  c->add_flag("--quiet,-q", a->quiet, "no line per finished variation");
  add_watchdog(c);
  cmds.push_back({c, [a] { return app::run_study(*a); }});
}

void add_render(CLI::App& cli, Commands& cmds) {
  auto a = std::make_shared<app::RenderArgs>();
  auto* c = cli.add_subcommand(
      "render",
      "Draw the pictures of a result directory of vmsim run or motion: the part under a raking light, "
      "its deviation maps, charts of the drive signals (PNG, no display needed)");
  c->add_option("DIR", a->dir, "result directory (surface.csv, deviation.csv, signals.csv, report.json)")
      ->required()
      ->check(CLI::ExistingDirectory);
  add_out(c, a->out_dir, "where the PNG files go (default: DIR/images)");
  c->add_option("--size", a->images.size, "WIDTHxHEIGHT in pixels (default 1600x1200)");
  c->add_option("--exaggeration", a->images.exaggeration, "vertical exaggeration of the part pictures")
      ->check(CLI::PositiveNumber);
  c->add_option("--region", a->images.region,
                "X_MIN,X_MAX,Y_MIN,Y_MAX (mm): zoom on this region instead of the deepest mark")
      ->delimiter(',')
      ->expected(4);
  c->add_option("--limit-um", a->images.limit_um,
                "colour limits of the deviation maps, +-um (default: max |deviation| rounded up)")
      ->check(CLI::PositiveNumber);
  c->add_option("--isolines", a->images.isolines, "iso-deviation lines per side of zero (default 3)")
      ->check(CLI::Range(0, 20));
  c->add_option("--magnification", a->images.magnification,
                "of the mark's departure from the reference in part_mark.png (default: from its depth)")
      ->check(CLI::PositiveNumber);
  c->add_option("--path-direction-deg", a->images.path_direction_deg,
                "cutting direction in the XY plane for the along-the-path views (default: the axis that travels "
                "furthest)");
  cmds.push_back({c, [a] { return app::run_render(*a); }});
}

void add_stats(CLI::App& cli, Commands& cmds) {
  auto a = std::make_shared<app::StatsArgs>();
  auto* c = cli.add_subcommand(
      "stats",
      "Print a surface file's size, spacing, invalid points and ISO 25178-2 areal parameters as JSON (a "
      "profile: its ISO 21920-2 profile parameters)");
  c->add_option("SURFACE", a->surface,
                "X3P, SDF, .sur, BCR-STM, CSV, ASCII x y z or matrix grid (also gzip-compressed), or a profile "
                "(Dektak CSV, X3P PRF, .sur profile): its ISO 21920-2 profile parameters")
      ->required()
      ->check(CLI::ExistingFile);
  add_surface_options(c, a->options, false);
  cmds.push_back({c, [a] { return app::run_stats(*a); }});
}

void add_compare(CLI::App& cli, Commands& cmds) {
  auto a = std::make_shared<app::CompareArgs>();
  auto* c = cli.add_subcommand(
      "compare",
      "Hold a measured scan against a predicted surface: registration, deviation (X3P), marks, areal "
      "parameters, report.json, pictures");
  c->add_option("--measured,-m", a->measured,
                "the measured scan (X3P, SDF, .sur, BCR-STM, CSV, ASCII grids) or profile (Dektak CSV, X3P PRF)")
      ->required()
      ->check(CLI::ExistingFile);
  c->add_option("--predicted,-p", a->predicted,
                "the predicted surface (e.g. vmsim run's surface.x3p) or part mesh (.stl)")
      ->required()
      ->check(CLI::ExistingFile);
  add_out(c, a->out_dir);
  c->add_option("--align", a->align, "auto (robust 6-DoF registration, default) or none");
  c->add_option("--align-init", a->align_init,
                "X,Y,Z,RX,RY,RZ (mm, deg): start of the registration, or with --align none the transform")
      ->delimiter(',')
      ->expected(6);
  c->add_option("--align-region", a->align_regions,
                "XMIN,XMAX,YMIN,YMAX (mm, prediction frame), repeatable: align only on these areas (the unmachined "
                "reference faces)");
  c->add_option("--loss", a->loss, "robust loss of the registration: tukey (default) or huber");
  add_surface_options(c, a->options, true);
  c->add_option("--mark-threshold", a->mark_threshold, "marks: |deviation| above this (default 1um)");
  c->add_option("--path-direction-deg", a->path_direction_deg,
                "the tool path's direction in XY for the marks' width and length (default: the prediction's lay)");
  add_no_render(c, a->no_render, "draw no pictures");
  c->add_option("--profile-line", a->profile_line,
                "a measured profile: X0,Y0,X1,Y1 (mm, prediction frame), the line across the prediction it was "
                "measured along");
  cmds.push_back({c, [a] { return app::run_compare(*a); }});
}

void add_measure(CLI::App& cli, Commands& cmds) {
  auto a = std::make_shared<app::MeasureArgs>();
  auto* c = cli.add_subcommand(
      "measure", "Simulate a confocal point sensor scanning a predicted surface, to plan a scan: what it resolves");
  c->add_option("PRED", a->predicted, "the predicted surface (e.g. vmsim run's surface.x3p)")
      ->required()
      ->check(CLI::ExistingFile);
  c->add_option("--step", a->step, "scan grid step (default 5um)");
  c->add_option("--spot", a->spot, "spot diameter, full width at half maximum (default 4um)");
  c->add_option("--noise", a->noise, "height noise, standard deviation (default 0.05um)");
  c->add_option("--max-slope-deg", a->max_slope_deg, "steeper flanks give no signal (default 30)")
      ->check(CLI::Range(0.1, 90.0));
  c->add_option("--dropout", a->dropout, "probability of a random dropout per point (default 0)")
      ->check(CLI::Range(0.0, 0.99));
  c->add_option("--seed", a->seed, "seed of the noise and dropouts (default 1)");
  c->add_option("--area", a->area, "XMIN,XMAX,YMIN,YMAX (mm): the scanned area (default: all)")
      ->delimiter(',')
      ->expected(4);
  c->add_option("--reference", a->reference,
                "reference surface (e.g. vmsim run's reference.x3p): report which predicted marks the scan resolves")
      ->check(CLI::ExistingFile);
  c->add_option("--mark-threshold", a->mark_threshold, "marks: |deviation| above this (default 1um)");
  add_out(c, a->out_dir);
  cmds.push_back({c, [a] { return app::run_measure(*a); }});
}

void add_identify_friction(CLI::App& cli, Commands& cmds) {
  auto a = std::make_shared<app::IdentifyFrictionArgs>();
  auto* c = cli.add_subcommand(
      "identify-friction",
      "Identify an axis' friction law and inertia from a trace of time, position or velocity, current");
  c->add_option(
       "TRACE", a->trace,
       "CSV (t_s, current_A, position_mm|position_deg|velocity_mm_per_s|velocity_deg_per_s) or MATLAB .mat (--mat)")
      ->required()
      ->check(CLI::ExistingFile);
  c->add_option("--torque-constant", a->torque_constant_Nm_per_A, "motor torque constant Kt (N m/A)")
      ->check(CLI::PositiveNumber);
  c->add_option("--lead-mm", a->lead_mm, "screw lead of a linear axis (mm per motor revolution)")
      ->check(CLI::PositiveNumber)
      ->excludes(
          c->add_option("--gear-deg-per-rev", a->gear_deg_per_rev, "gear of a rotary axis (deg per motor revolution)")
              ->check(CLI::PositiveNumber));
  c->add_option("--machine", a->machine, "machine file giving Kt, lead or gear and gravity of --axis")
      ->check(CLI::ExistingFile)
      ->needs(c->add_option("--axis", a->axis, "axis name in the machine file (X Y Z A B C)"));
  c->add_option("--gravity", a->gravity, "gravity model: auto (default), none, constant, tilting")
      ->check(CLI::IsMember({"auto", "none", "constant", "tilting"}));
  c->add_option("--smoothing-ms", a->smoothing_ms, "differentiation window (default 10 ms)")
      ->check(CLI::PositiveNumber);
  c->add_option("--mat", a->mat,
                ".mat trace: t=VAR,position=VAR|velocity=VAR,control=VAR (e.g. t=t,position=qm,control=vir)");
  c->add_option("--trace-unit", a->trace_unit, "position unit of a .mat trace: mm (default), m, in, deg, rad")
      ->check(CLI::IsMember({"mm", "m", "in", "deg", "rad"}));
  c->add_option("--control-gain", a->control_gain,
                "the current column (CSV) or control variable (.mat) times this is the load-side force, N (linear "
                "axis), or torque, N m (rotary): a control signal instead of a motor current (replaces Kt and the "
                "lead or gear; results also given at the load)")
      ->check(CLI::PositiveNumber);
  add_out(c, a->out_dir, "write drive_identified.toml, friction_fit.csv, report.json here");
  cmds.push_back({c, [a] { return app::run_identify_friction(*a); }});
}

// Duong et al.: offline gain adjustment of a biaxial profile.
void add_oga(CLI::App& cli, Commands& cmds) {
  auto a = std::make_shared<app::OgaArgs>();
  auto* c = cli.add_subcommand(
      "oga",
      "Offline gain adjustment (Duong et al.): admissible gains per axis, the best fixed pair (C1), a position-gain "
      "schedule by receding windows (C2) for [job] gain_schedule, MSE(CE) C1 vs C2, limits, currents, charts");
  add_job(c, a->job, "job file of a biaxial profile (two of X Y Z move)");
  add_out(c, a->out_dir);
  c->add_option("--kp-grid", a->kp_grid, "Kv values swept, MIN:STEP:MAX in (m/min)/mm (default 1:0.5:9)");
  c->add_option("--kf-grid", a->kf_grid, "KF values swept, MIN:STEP:MAX (default 0:0.1:1.2)");
  c->add_option("--range", a->ranges,
                "Kv range of the schedule, MIN:MAX for every axis or AXIS=MIN:MAX, repeatable (default: [Kv1 - 1, "
                "Kv1 + 0.5] around C1 within the admissible Kv, as Duong et al.'s [5, 6.5] around 6)");
  c->add_option("--dk", a->gain_step, "gain step dK of the candidates, (m/min)/mm (default 0.03)");
  c->add_option("--frequency-hz", a->frequency_hz,
                "f of the gain function's sinusoid, eq. 3 (default 10: p = 50 at Te 1 ms)");
  c->add_option("--reference", a->reference,
                "C1: best (the best admissible fixed pair, default) or machine (the machine file's gains)")
      ->check(CLI::IsMember({"best", "machine"}));
  c->add_option("--straight-curvature", a->straight_curvature_per_mm,
                "windows: |curvature| below this is straight, 1/mm (default 1e-4)");
  c->add_option("--transition-rate", a->transition_rate_per_mm2,
                "windows: a transition where the curvature changes faster than this, 1/mm^2 (default 0.01)");
  c->add_option("--min-window-rows", a->min_window_rows, "windows: shorter runs join the one before (default 3)");
  c->add_option("--lead-in-rows", a->lead_in_rows, "rows before a window in its contour error (default 100)");
  c->add_option("--settle-s", a->settle_s, "simulated after the last setpoint, s (default 0.2)");
  c->add_flag("--from-start", a->from_start,
              "simulate every candidate from the first instant, as Duong et al. (same answer, slower)");
  c->add_option("--limits", a->limits,
                "the limits that judge the configurations and the candidates: all (default), none, or a "
                "comma-separated list of velocity, acceleration, jerk, current (report.json's admissible_by_limit "
                "counts each alone)");
  c->add_option("--threads", a->threads, "OpenMP threads (default: all; the result does not depend on it)");
  add_no_render(c, a->no_render, "draw no charts (by default: PNG files in OUT/images)");
  add_image_size(c, a->image_size, "size of the charts, WIDTHxHEIGHT (default 1600x900)");
  add_watchdog(c);
  cmds.push_back({c, [a] { return app::run_oga(*a); }});
}

// Chen et al. 2016: contour-error-constrained feed planning.
void add_plan_feed(CLI::App& cli, Commands& cmds) {
  auto a = std::make_shared<app::PlanFeedArgs>();
  auto* c = cli.add_subcommand(
      "plan-feed",
      "Plan the feed along a job's path so the servo's contour error stays within a tolerance (Chen et "
      "al. 2016: a linear program on the squared feed), play it through the interpolator and the drives");
  add_job(c, a->job, "job file with a [feedplan] table");
  add_out(c, a->out_dir);
  add_no_render(c, a->no_render, "draw no charts (by default: PNG files in OUT/images)");
  cmds.push_back({c, [a] { return app::run_plan_feed(*a); }});
}

// The predictive-compensation paper: identification signals, transfer-function identification, compensation.
void add_excite(CLI::App& cli, Commands& cmds) {
  auto a = std::make_shared<app::ExciteArgs>();
  auto* c = cli.add_subcommand(
      "excite",
      "Write the predictive-compensation paper's identification signal for one axis (inverse M-sequence or "
      "PRBS, eq. 8-15) as a G-code program or a setpoint CSV; --simulate also writes the trace the machine "
      "file's drive gives");
  c->add_option("AXIS", a->axis, "axis name (X Y Z A B C)")->required();
  c->add_option("--machine,-m", a->machine, "machine file")->required()->check(CLI::ExistingFile);
  c->add_option("--out,-o", a->out, "output: .ngc (G-code) or .csv (t_s and the setpoint every Te)")->required();
  c->add_option("--signal", a->signal, "inverse-m (default: no DC, the predictive-compensation paper) or prbs");
  c->add_option("--bits", a->bits, "shift-register length n, 2..20 (default: from --resolution-hz)");
  c->add_option("--resolution-hz", a->resolution_hz, "lowest frequency resolved, 1 / signal period (default 1)");
  c->add_option("--bandwidth-hz", a->bandwidth_hz,
                "axis bandwidth the signal covers: Td = q Te with 0.433 / Td >= B (default 100, the "
                "predictive-compensation paper)");
  c->add_option("--td-ms", a->td_ms, "minimum switching interval Td in ms (overrides --bandwidth-hz)");
  c->add_option("--amplitude", a->amplitude, "a: +-a about the ramp, mm or deg (default 0.05)");
  c->add_option("--feed", a->feed,
                "constant velocity the signal rides on, mm/min or deg/min, so the axis never reverses and Coulomb "
                "friction stays constant (default 1200; 0: about a fixed point)");
  c->add_option("--periods", a->periods, "signal periods (default 4: identify on 2, validate on 2)");
  c->add_option("--start", a->start, "start position, mm or deg (default: centred in the travel)");
  c->add_option("--period-ms", a->period_ms, "sampling period Te in ms (default 1)");
  c->add_option("--simulate", a->simulate,
                "also run the setpoints through the axis's [axes.drive] and write this position trace CSV");
  cmds.push_back({c, [a] { return app::run_excite(*a); }});
}

void add_identify(CLI::App& cli, Commands& cmds) {
  auto a = std::make_shared<app::IdentifyArgs>();
  auto* c = cli.add_subcommand(
      "identify",
      "Identify each axis as a discrete transfer function from a position trace (ARX, ARMAX, OE; the "
      "predictive-compensation paper), validate, rank, and write axis_models.toml for jobs to run on");
  c->add_option("--trace,-t", a->traces,
                "position trace: CSV (t_s, <AXIS>_command_mm, <AXIS>_actual_mm, ...: vmsim motion's trace.csv), "
                "LinuxCNC halscope log or MATLAB .mat; repeat it for several experiments, identified together")
      ->required();
  c->add_option("--channel", a->channels,
                "halscope log: AXIS=COMMAND_PIN,ACTUAL_PIN, repeatable (default: joint.N.motor-pos-cmd as axis "
                "XYZABC[N] with joint.N.motor-pos-fb or the log's one *encoder*.position pin)");
  c->add_option("--mat", a->mat, ".mat trace: t=VAR,command=VAR,actual=VAR[,axis=X] (e.g. t=t,command=qg,actual=qm)");
  c->add_option("--trace-unit", a->trace_unit,
                "position unit of halscope and .mat traces: mm (default), m, in, deg, rad")
      ->check(CLI::IsMember({"mm", "m", "in", "deg", "rad"}));
  c->add_option("--rest-offset", a->rest_offsets,
                "AXIS=VALUE (mm or deg): encoder minus command at rest, for traces that start mid-motion (default: "
                "measured on the trace's first still stretch), repeatable");
  c->add_option("--validate", a->validate,
                "a separate validation trace (default: one trace's second half, or with several traces the last one)");
  c->add_option("--axis", a->axes, "axes to identify, repeatable (default: every axis in the trace)");
  c->add_option("--structure,-s", a->structure, "arx, armax, oe or all (default)");
  c->add_option("--orders", a->orders, "NB,NA: numerator and denominator orders (default 2,5) or auto (BIC)");
  c->add_option("--nc", a->nc, "ARMAX noise numerator order (default 2)");
  c->add_option("--delay", a->delay, "input delay nk in samples, or auto (default)");
  c->add_option("--use", a->use,
                "structure written to the model file: best (lowest validation MSE, marginal models last; default), "
                "arx, armax or oe");
  add_out(c, a->out_dir, "output directory for axis_models.toml and report.json");
  cmds.push_back({c, [a] { return app::run_identify(*a); }});
}

void add_compensate(CLI::App& cli, Commands& cmds) {
  auto a = std::make_shared<app::CompensateArgs>();
  auto* c =
      cli.add_subcommand("compensate",
                         "Predict a job's contour error and add it back to the setpoints (the predictive-compensation "
                         "paper): compensated setpoints, a compensated G-code program, contour error before and after");
  add_job(c, a->job);
  add_out(c, a->out_dir);
  c->add_option("--axis-models", a->axis_models,
                "predict with these identified models (default: the job's [job] axis_models, else the machine's "
                "cascades)");
  c->add_option("--buffer", a->buffer_samples, "foot-point search buffer m, odd (default 0: automatic)");
  c->add_option("--iterations", a->max_iterations, "largest number of corrections (default 6)");
  c->add_option(
      "--smoothing", a->smoothing_samples,
      "standard deviation of the correction's Gaussian smoothing along the setpoints, in samples (default 4)");
  add_no_render(c, a->no_render, "draw no chart (by default: OUT/images/contour_error.png)");
  c->add_flag("--tip-only", a->tip_only,
              "five-axis machines: correct the tool tip only (default: the tool axis' orientation error too)");
  c->add_flag("--dense-program", a->dense_program,
              "also write compensated_dense.ngc: the compensated setpoints as one G93 block per period Te");
  cmds.push_back({c, [a] { return app::run_compensate(*a); }});
}

int run_command(int argc, char** argv) {
  CLI::App cli{
      "vmsim - virtual machining: predicts the surface a CNC milling machine really cuts, from the program\n"
      "through the NC interpolator, the servo drives and the kinematics to material removal and metrology."};
  cli.set_version_flag("--version", std::string("vmsim ") + VMSIM_VERSION);
  cli.require_subcommand(1);
  cli.fallthrough(false);
  Commands cmds;
  for (auto add : {add_canon, add_interp, add_identify_friction, add_motion, add_oga, add_run, add_study, add_render,
                   add_stats, add_compare, add_measure, add_plan_feed, add_excite, add_identify, add_compensate})
    add(cli, cmds);
  try {
    cli.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return cli.exit(e);
  }
  try {
    for (const Command& c : cmds)
      if (*c.sub) return c.run();
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

// MPI (when launched by mpirun) wraps the whole command; an error on one rank ends all ranks (no hang).
int main(int argc, char** argv) {
  vmsim::app::mpi_start(&argc, &argv);
  const int code = run_command(argc, argv);
  if (code != 0) vmsim::app::mpi_abort_all(code);
  vmsim::app::mpi_finish();
  return code;
}
