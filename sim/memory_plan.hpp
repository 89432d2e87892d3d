#pragma once
// The memory a run will need, before it runs (`vmsim run --plan`): the field and the copies a run holds (the stock
// it starts from, the reference), the motion and the sweeps (counted exactly: the program is interpolated and
// simulated, nothing is cut), the outputs, per process and per rank of a tiled run under MPI, with advice for a
// memory per rank. Its assumptions are listed in the plan; bench/README.md holds its ratios to measured peaks.
//
// The model (bytes), with R the rays of a tile, S the setpoint samples, a the machine's axes, W the sweeps:
//   field      8 R + 56 per row (removal::IntervalStore::initial_bytes: before cuts split rays), times the copies a
//              run holds: the field, the stock it started from (kept for reference "stock"), and the reference
//              field (kinds feed, program, stock, job);
//   motion     an actual motion is streamed (sim/motion_stream.hpp): S max(8 a + 20 + 16 interpolation,
//              8 a + 12 + 72 drives in blocks, 88 contour error) (+24 turning axis); other motions (setpoints,
//              program) S (8 a + 20 setpoints + 64 a drives + 60 contour error + 48 pose track
//              (+24 turning axis) + 8 (4 a + 6) signals);
//   sweeps     96 W (removal::SweptTool);
//   gather     rank 0 of a gathered run: the whole field and reference, plus 12 B per ray of the largest grid
//              (interval counts and ends in flight);
//   outputs    where the whole part is written (one process, or rank 0 when gathered): 136 B per height-grid node
//              (three grids, the part mesh with its deviation, its writer's copy) for a z-map, 24 B where the
//              mesh is not written ([outputs] part_mesh, large_grid_nodes: a run makes it only to write it); for a
//              tri-dexel field its level set and mesh (removal::estimate_level_set_bytes / estimate_mesh_bytes over
//              twice the stock's box area, for the part and the reference); --tiles-out: 24 B per node of the tile;
//   base       the process itself (libraries, code): 70 MB, measured (bench/README.md).
// Not modelled: rays a cut splits (their extra intervals; the report's memory_bytes shows them), the pictures'
// renderer, the allocator's slack. bench/README.md compares the model with measured peak RSS.
#include "core/job.hpp"
#include "sim/plan_motion.hpp"

#include <nlohmann/json.hpp>

#include <optional>

namespace vmsim::sim {

struct MemoryPlanOptions {
  double feed_scale = 1.0;
  int ranks = 1;                                // of a tiled run
  std::optional<double> memory_per_rank_bytes;  // advice: ranks (gathered, tiles out) or a spacing that fit in it
};

// The plan as plan.json holds it: field (kind, grids, rays, bytes), reference_field, motion, one_process (bytes by
// part and total_bytes), ranks, gathered and tiles_out (per_rank, largest_rank_bytes), advice, assumptions.
// Throws core::Error for a rank count the field cannot be split into, or a job that cannot run.
// The motion's bytes per setpoint sample in the model above (setpoints, drives, contour error, track, signals), for
// a machine of `axes` axes; `turning`: the track holds a tool axis too.
double motion_bytes_per_setpoint(int axes, bool turning);
// The same for the run's own actual motion, streamed (sim/motion_stream.hpp): the largest of its stages -- the
// interpolation (setpoints and the interpolator's arrays), the drives in blocks (setpoints, the track, the commanded
// tip) and the contour error (its inputs and its own arrays).
double streamed_motion_bytes_per_setpoint(int axes, bool turning);

// Computes the run's motions (sim/plan_motion.hpp) once the options and the field are checked, and hands them to
// `motions` when given (sim/time_plan.hpp's plan_time takes them).
nlohmann::json plan_memory(const core::Job& job, const MemoryPlanOptions& options = {},
                           core::Progress& progress = core::no_progress(), PlannedMotions* motions = nullptr);

}  // namespace vmsim::sim
