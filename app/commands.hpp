#pragma once
// The vmsim subcommands. main.cpp parses the command line (CLI11) and calls these; each returns the
// process exit code and throws core::Error for input a user must fix.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::app {

// vmsim canon PROGRAM [--tool-table F] [--no-motion-m LIST] [--dialect D] [--lenient]: LinuxCNC's canonical calls on
// stdout (as `rs274 -g` for G-code; the same vocabulary for Sinumerik 840D programs), warnings on stderr.
struct CanonArgs {
  std::filesystem::path program;
  std::optional<std::filesystem::path> tool_table;
  std::vector<int> no_motion_mcodes;
  std::string dialect = "auto";
  bool lenient = false;
};
int run_canon(const CanonArgs& args);

struct InterpArgs {
  std::filesystem::path job;
  std::optional<std::filesystem::path> out_dir;  // default: NAME_COMMAND/ in the current directory (app/report.hpp)
  std::optional<double> feed_scale;              // multiplies every programmed feed (override, as on the NC panel)
  bool summary_only = false;                     // print the summary, write no file
};
// vmsim interp JOB: setpoints.csv (t, each axis, path speed) and the cycle time.
int run_interp(const InterpArgs& args);

struct MotionArgs {
  std::filesystem::path job;
  std::optional<std::filesystem::path> out_dir;  // default: NAME_COMMAND/ in the current directory (app/report.hpp)
  std::optional<double> feed_scale;
  bool full_rate_trace = false;  // also write every current-loop sample (large)
};
// vmsim motion JOB: setpoints through the servo drives; actual positions, tracking and contour errors, currents
// (CSV), report.json.
int run_motion(const MotionArgs& args);

struct RunArgs {
  std::filesystem::path job;
  std::optional<std::filesystem::path> out_dir;  // default: NAME_COMMAND/ in the current directory (app/report.hpp)
  std::optional<double> feed_scale;
  bool quiet = false;                    // no progress on stderr
  bool no_render = false;                // no pictures in DIR/images
  std::string image_size = "1600x1200";  // WIDTHxHEIGHT of the pictures
  // Under mpirun: each rank writes its tile (DIR/tiles/*.x3p) and rank 0 the manifest DIR/tiles.json, instead of
  // gathering the whole field to rank 0 (app/tiled_run.hpp).
  bool tiles_out = false;
  // --plan: no run; the memory the job needs (whole and per rank) and advice (app/run_plan.hpp).
  bool plan = false;
  std::optional<int> ranks;                  // --ranks N for the plan (default: the MPI world size)
  std::optional<double> memory_per_rank_gb;  // --memory-per-rank-gb for the plan's advice
};
// vmsim run JOB: the whole chain to the machined surface and its marks; report.json, height grids, part mesh,
// signals.csv, and the pictures in DIR/images (app/result_images).
int run_run(const RunArgs& args);

// Picture options shared by vmsim render (and the defaults vmsim run uses).
struct ImageArgs {
  std::string size = "1600x1200";            // WIDTHxHEIGHT
  double exaggeration = 1.0;                 // vertical exaggeration of the part pictures
  std::vector<double> region;                // X_MIN,X_MAX,Y_MIN,Y_MAX (mm): the zoom pictures' region
  std::optional<double> limit_um;            // colour limits of the deviation maps (default: max |deviation|)
  int isolines = 3;                          // iso-deviation lines per side of zero
  std::optional<double> magnification;       // of the mark's relief in part_mark.png (default: from its depth)
  std::optional<double> path_direction_deg;  // cutting direction in XY for the along-the-path views
};
struct RenderArgs {
  std::filesystem::path dir;                     // a result directory of vmsim run or vmsim motion
  std::optional<std::filesystem::path> out_dir;  // default: DIR/images
  ImageArgs images;
};
// vmsim render DIR: the part, deviation and chart pictures of a result directory (PNG), their paths on stdout.
int run_render(const RenderArgs& args);

// ---- surface commands: measured scans against predicted surfaces (metrology) ----

// Processing before areal parameters, shared by stats and compare.
struct SurfaceOptions {
  std::string level = "plane";       // form removed first: none | plane | poly:N (a profile: mean, line, polynomial)
  std::vector<std::string> filters;  // S:<cut-off> and/or L:<cut-off> (Gaussian, ISO 16610-61 / -21), in order
  double outlier_sigma = 0.0;        // mask spikes departing more than this many robust sigmas (0: keep all)
  std::string profile_range;         // profiles: "X0,X1" (lengths), the part of the trace evaluated
};

struct StatsArgs {
  std::filesystem::path surface;  // X3P, SDF, .sur, CSV, ASCII x y z or matrix
  SurfaceOptions options;
};
// vmsim stats SURFACE: size, spacing, invalid points and the ISO 25178-2 areal parameters, as JSON on stdout.
int run_stats(const StatsArgs& args);

struct CompareArgs {
  std::filesystem::path measured, predicted;     // scan (any surface format); prediction (a surface, or an STL mesh)
  std::optional<std::filesystem::path> out_dir;  // default: NAME_COMMAND/ in the current directory (app/report.hpp)
  std::string align = "auto";                    // auto: robust registration; none: the scan as it lies
  std::vector<double> align_init;                // X,Y,Z mm, RX,RY,RZ deg: start (auto) or the transform (none)
  std::vector<std::string> align_regions;        // XMIN,XMAX,YMIN,YMAX (mm, prediction frame): align on these only
  std::string loss = "tukey";                    // tukey | huber
  SurfaceOptions options{"plane", {}, 6.0, ""};  // outliers masked in the scan at 6 sigma by default
  std::string mark_threshold = "1um";            // marks: |deviation| above this
  std::optional<double> path_direction_deg;  // the path direction for the marks (default: the lay of the prediction)
  bool no_render = false;                    // no pictures
  std::string profile_line;                  // a measured profile: "X0,Y0,X1,Y1" (mm), the line across PRED
};
// vmsim compare --measured SCAN --predicted PRED: registration, deviation grid (X3P), statistics, marks, areal
// parameters of both and their differences, report.json, pictures.
int run_compare(const CompareArgs& args);

struct MeasureArgs {
  std::filesystem::path predicted;
  std::optional<std::filesystem::path> reference;  // to see which marks the scan resolves (e.g. vmsim run's reference)
  std::optional<std::filesystem::path> out_dir;    // default: NAME_COMMAND/ in the current directory (app/report.hpp)
  std::string step = "5um", spot = "4um", noise = "0.05um";
  double max_slope_deg = 30.0;
  double dropout = 0.0;
  unsigned seed = 1;
  std::vector<double> area;  // XMIN,XMAX,YMIN,YMAX mm (default: all of PRED)
  std::string mark_threshold = "1um";
};
// vmsim measure PRED: the scan a confocal sensor would take of the predicted surface (scan.x3p) and what it resolves.
int run_measure(const MeasureArgs& args);

struct PlanFeedArgs {
  std::filesystem::path job;                     // a job with a [feedplan] table
  std::optional<std::filesystem::path> out_dir;  // default: NAME_COMMAND/ in the current directory (app/report.hpp)
  bool no_render = false;                        // no charts
};
// vmsim plan-feed JOB: Chen et al.'s contour-error-constrained feed plan (drives/feedplan), played by the interpolator
// and simulated through the servo: feed_profile.csv, motion.csv, report.json, charts.
int run_plan_feed(const PlanFeedArgs& args);

}  // namespace vmsim::app
