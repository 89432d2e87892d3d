#pragma once
// vmsim run --plan JOB: a dry run. The motion is computed (it is cheap and gives the exact sample and sweep counts);
// the stock is not made. Prints, and writes as DIR/plan.json with --out, the memory model of the run: dexel counts
// and bytes of the field, its copies, the motion and its signals, the sweeps, the surfaces and meshes, for one
// process and per rank of a tiled run (--ranks N, or the MPI world size), and advice for a memory per rank.
//
// The model (bytes), with R the rays of a tile, S the setpoint samples, a the machine's axes, W the sweeps:
//   field      8 R + 56 per row (removal::IntervalStore::initial_bytes: before cuts split rays), times the copies a
//              run holds: the field, the stock it started from (kept for reference "stock"), and the reference
//              field (kinds feed, program, stock, job);
//   motion     S (8 a + 20 setpoints + 64 a drives + 60 contour error + 48 pose track (+24 turning axis) +
//              8 (4 a + 6) signals), for the job's motion and the reference's;
//   sweeps     96 W (removal::SweptTool);
//   gather     rank 0 of a gathered run: the whole field and reference, plus 12 B per ray of the largest grid
//              (interval counts and ends in flight);
//   outputs    where the whole part is written (one process, or rank 0 when gathered): 136 B per height-grid node
//              (three grids, the part mesh with its deviation, its writer's copy) for a z-map; for a tri-dexel
//              field its level set and mesh (removal::estimate_level_set_bytes / estimate_mesh_bytes over twice
//              the stock's box area, for the part and the reference); --tiles-out: 24 B per node of the tile;
//   base       the process itself (libraries, code): 70 MB, measured (bench/README.md).
// Not modelled: rays a cut splits (their extra intervals; the report's memory_bytes shows them), the pictures'
// renderer, the allocator's slack. bench/README.md compares the model with measured peak RSS.
#include "app/commands.hpp"
#include "core/job.hpp"

namespace vmsim::app {

int run_plan(const core::Job& job, const RunArgs& args);

}  // namespace vmsim::app
