#pragma once
// A job: which machine runs which program with which tool on which stock, and how the NC interpolates.
// Loaded from job.toml; the schema is documented in parts/README.md.
#include "core/machine.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::core {

enum class ToolShape { Ball, Flat, BullNose };

struct ToolSpec {
  ToolShape shape = ToolShape::Ball;
  double diameter_mm = 10.0;
  double corner_radius_mm = 5.0;  // ball: D/2, flat: 0, bull-nose: given
  double flute_length_mm = 20.0;
  double length_mm = 50.0;  // gauge length, spindle nose to tip
  // [[tools]]: the program's T word this tool answers to (-1: by name only), and (840D T="name") its name; 0 and
  // empty in [tool].
  int number = 0;
  std::string name;
};

struct StockSpec {
  // Box; a closed triangle mesh (binary or ASCII STL); or the part another job leaves (Kind::Job).
  enum class Kind { None, Box, Mesh, Job } kind = Kind::None;
  Eigen::Vector3d min_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d max_mm = Eigen::Vector3d::Zero();
  std::filesystem::path mesh_file;  // Kind::Mesh
  std::filesystem::path job_file;   // Kind::Job
};

// How material is removed (the feed-drive simulation paper section 4).
struct RemovalSpec {
  // The kernel: dexels (exact along their rays) or an OpenVDB narrow-band level set (removal/vdb_part.hpp: isotropic
  // to within its voxel, watertight meshes). With "vdb", `field` only chooses the outputs (height grid, or needles).
  enum class Method { Dexel, Vdb } method = Method::Dexel;
  double voxel_mm = 0.05;        // vdb: level-set voxel size (default: spacing_mm)
  double mesh_adaptivity = 0.0;  // vdb and tri-dexel: volumeToMesh adaptivity in [0, 1] of the part mesh
  enum class Field { ZMap, TriDexel, NBuffer } field = Field::ZMap;
  double spacing_mm = 0.05;  // ray spacing of z-map and tri-dexel grids
  // Whose motion cuts: the drives' actual positions (the marks come from the drives), the interpolator's
  // setpoints, or the programmed path itself (the feed-drive simulation paper section 1: to separate interpolator and
  // drive effects).
  enum class Motion { Actual, Setpoints, Program } motion = Motion::Actual;
  double track_tolerance_mm = 1e-4;  // largest distance between the removed motion and the sampled poses
  // Whether the job gave track_tolerance_mm. If not, method "vdb" cuts a turning tool (5-axis) at voxel_mm / 10
  // (app/cmd_run.cpp, parts/README.md): its sub-steps are exact sweeps, each evaluated at every band voxel it
  // reaches, and at 1e-4 mm a tool of 6 mm reach needs about 1000 of them per degree of rotation.
  bool track_tolerance_given = false;
  std::filesystem::path needles_file;  // NBuffer: CSV x,y,z,nx,ny,nz (mm): needles through points along normals
  double needle_half_length_mm = 1.0;  // each needle runs from point - L n to point + L n
};

// What the predicted surface is compared with to find the marks.
struct ReferenceSpec {
  // The same program cut exactly along its programmed path (the nominal cut); the same program through the same
  // chain with its feeds scaled (the feed-drive simulation paper's low-feed reference); the part another job leaves;
  // the stock this job starts from; or nothing.
  enum class Kind { Program, Feed, Job, Stock, None } kind = Kind::Program;
  double feed_scale = 0.01;        // Kind::Feed
  std::filesystem::path job_file;  // Kind::Job
};

struct InterpSpec {
  double period_s = 1e-3;       // Te
  double tolerance_mm = 0.020;  // largest distance of a setpoint from the programmed geometry
  // Whether the job gave tolerance_mm; if not, a program that sets its own (Sinumerik CYCLE832,
  // core::ToolPath::program_tolerance_mm) is interpolated with that.
  bool tolerance_given = false;
  // The most setpoints a job may make (max_setpoints): the interpolator refuses a program whose lower-bound count
  // (from its lengths, feeds and the axes' velocity limits) is larger, before making any - a typo such as F0.01 or
  // period_ms = 0.001 would otherwise fill the memory. 2e7 is 5.6 hours at 1 ms.
  double max_setpoints = 2e7;
};

// [feedplan]: Chen et al.'s contour-error-constrained feed planning (vmsim plan-feed, drives/feedplan).
struct FeedPlanSpec {
  double chord_error_mm = 0.0005;           // delta_max (Chen et al. 2016 eq. 15)
  double contour_error_mm = 0.020;          // eps0 (eq. 8)
  std::optional<double> max_feed_mm_per_s;  // f_max (eq. 17); default: the program's highest feed
  double sample_spacing_mm = 0.05;          // arc length between the plan's samples
  int window_samples = 4000;                // samples per linear program (longer paths: overlapping windows)
  bool jerk = true;                         // also keep the axes' jerk limits (beyond the seed)
  bool verify = true;                       // simulate the plan, tighten it where the simulated error exceeds eps0
  struct Nurbs {                            // [feedplan.nurbs]: the path, instead of [job] program
    int degree = 3;
    std::filesystem::path control_points, knots;  // CSV: index,x,y,z,weight and index,knot
  };
  std::optional<Nurbs> nurbs;
  // The servo of the contour-error model and the simulation: the machine's cascades ([axes.drive], linearised by
  // drives/linear_model), Chen et al.'s PID servo (eq. 2) or a continuous transfer function, given per moving axis.
  enum class Servo { Machine, Pid, TransferFunction } servo = Servo::Machine;
  struct Axis {        // [[feedplan.axis]]
    std::string name;  // X Y Z
    double kp = 0, ki = 0, kd = 0, ka = 0, kt = 0, inertia = 0, damping = 0,
           rg = 0;                 // pid (Chen et al. 2016 Table 1 units)
    std::vector<double> num, den;  // transfer_function: descending powers of s
  };
  std::vector<Axis> axes;
};

// [outputs]: which heavy result files vmsim run writes (sim/run_outputs.hpp). A grid of more than large_grid_nodes
// nodes is "large": "auto" then writes no part mesh and no CSV grids (NPY and X3P hold the same heights).
struct OutputsSpec {
  enum class Mesh { Auto, Full, Simplified, None } part_mesh = Mesh::Auto;  // part.stl and part.vtp of a z-map
  enum class Csv { Auto, Always, Never } csv = Csv::Auto;                   // surface.csv, reference.csv, deviation.csv
  bool npy = true;  // surface.npy, deviation.npy, deviation_vertical.npy
  bool x3p = true;  // surface.x3p, reference.x3p, deviation.x3p
  double large_grid_nodes = 4e6;
  // The simplified mesh merges blocks of the grid that are flat to within this (its error bound is twice it).
  double mesh_tolerance_mm = 1e-4;
  int vtp_compression_level = 1;  // zlib level of part.vtp: 1 writes ~1.6x faster than VTK's 5, ~5 % larger
};

struct Job {
  std::string name;
  std::filesystem::path file;  // the job file itself
  std::filesystem::path machine_file;
  std::filesystem::path program_file;
  std::optional<std::filesystem::path> tool_table_file;
  std::vector<int> no_motion_mcodes;  // G-code M codes the machine remaps to actions without motion
  // Where the tool tip is before the program runs (workpiece frame). Without it the program's own start applies
  // (LinuxCNC: the origin, which with a tool length offset puts the tip below the origin).
  std::optional<Eigen::Vector3d> start_mm;
  // A gain schedule (vmsim oga, Duong et al.): per-setpoint position-loop gains the drives run with (CSV,
  // drives/oga_schedule.hpp); vmsim run and vmsim motion apply it to the job's own motion.
  std::optional<std::filesystem::path> gain_schedule_file;
  // A feed plan (vmsim plan-feed, Chen et al.): a feed ceiling along the path the interpolator follows (CSV,
  // methods/feedplan_file.hpp); every command that interpolates the job follows it (sim::Chain).
  std::optional<std::filesystem::path> feed_plan_file;
  // Identified axis models (TOML written by `vmsim identify`): these axes run as their identified transfer functions
  // instead of the machine file's [axes.drive] cascades (parts/README.md).
  std::optional<std::filesystem::path> axis_models_file;
  // G-code X Y Z are the tool tip in the workpiece frame and A B C the rotary axes (tool-centre-point programming,
  // LinuxCNC's M428 on xyzac-trt); false: the words are the machine's axes. Chain machines only (core/kinematics).
  bool tcp = false;
  // The program's language: "auto" (by extension and content), "rs274ngc", "sinumerik" or "apt" (program/program.hpp).
  std::string program_dialect = "auto";
  // Sinumerik and APT: statements known to have no motion that vmsim does not model are warnings, not errors.
  bool program_lenient = false;
  // APT CL files without UNITS/ (NX CLSF): "mm" or "inch"; empty: not given (such a file is read as mm with a warning).
  std::string program_units;
  Machine machine;
  ToolSpec tool;
  bool tool_given = false;  // the job has a [tool]; without one a CL program's own tool cuts (sim::use_program_tool)
  // [tool] all_tools = true: the one [tool] cuts for every T number the program calls (a deliberate simplification);
  // without it a program calling several different tools is refused (sim/tools.hpp).
  bool tool_all_numbers = false;
  // [[tools]]: one per T number (and 840D name) the program calls; every move is cut by the tool in the spindle.
  // Empty: the one `tool` cuts every move.
  std::vector<ToolSpec> tools;
  // Where `tool` came from when not from the job file: "file:line" of the CL program's TLDATA/ or CUTTER/
  // (sim::use_program_tool); empty otherwise.
  std::string tool_from_program;
  StockSpec stock;
  InterpSpec interp;
  RemovalSpec removal;
  ReferenceSpec reference;
  std::optional<FeedPlanSpec> feedplan;  // [feedplan]
  OutputsSpec outputs;                   // [outputs]
};

Job load_job(const std::filesystem::path& path);

}  // namespace vmsim::core
