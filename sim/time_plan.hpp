#pragma once
// The CPU time a run will take, predicted before it runs (`vmsim run --plan`), from counts known before cutting:
// the sweeps and, for each, the rays of each grid in its shadow (the rays whose lines cross its bounding box: the
// rays removal::cut lets it touch, removal::footprint), by the kernel path the sweep takes:
//   axial ball   a ball end whose axis lies along the grid's rays (the z-map's 3-axis kernel, removal/row_cut.inc);
//   general      any other ball or flat end (tilted, or across the rays): removal::ray_interval per ray;
//   bull-nose    a bull-nose on the general path (bracketed by flat-end sweeps and refined: dearer per ray).
// removal CPU s = sum over paths of cost per shadow ray x shadow rays, but for the axial ball a cost per tile of its
// shadow (its kernel settles most rays a tile at a time, so its cost follows the tiles, not the rays); whole run =
// removal + a cost per ray of the field (the stock, the surfaces and, for a z-map, the mesh, CSV and X3P files the
// job writes) + the motion (its CPU is measured while planning: the plan
// computes it anyway). The costs per shadow ray are averages over the kernels' culling (tiles, bounds): measured once
// (time_plan.cpp says on what, where and when), not tuned per case; bench/README.md compares the prediction with
// measured runs. Not modelled: the vdb method (not predicted), the reference's own cut, the pictures.
#include "core/job.hpp"
#include "core/progress.hpp"
#include "removal/fields.hpp"
#include "removal/swept_tool.hpp"
#include "sim/plan_motion.hpp"

#include <nlohmann/json.hpp>

#include <vector>

namespace vmsim::sim {

// The counts the prediction uses.
struct RemovalWork {
  double sweeps = 0;
  double axial_ball_rays = 0, general_rays = 0, bull_nose_rays = 0;  // shadow rays by kernel path, over all grids
  // The axial ball's shadow in the kernel's tiles (removal/cut.cpp: 8 rows x 4-32 columns): the tiles it touches, and
  // the shadow rays in those its bound over the tile does not settle against the tile's highest top, as the model
  // follows the tops down (each tile's top lowered to the sweep's highest point over it where the sweep covers it).
  double axial_ball_tiles = 0, axial_ball_open_rays = 0;
  double field_rays = 0;                                             // rays of the field (all grids)
  bool tridexel = false;
  // A z-map's outputs that cost per node (sim/run_outputs.cpp; plan_time sets them from the job's [outputs]).
  bool part_mesh = true, csv = true, x3p = true;
};

// The shadow counts of `sweeps` on the dexel field of a stock box at a spacing (the grids removal/fields.hpp makes:
// a z-map's rays along Z, a tri-dexel's along X, Y and Z, from the box's low corner every spacing_mm).
RemovalWork count_removal_work(const removal::Box& stock, double spacing_mm, bool tridexel,
                               const std::vector<removal::SweptTool>& sweeps);

// The predicted CPU seconds (removal and whole run) for those counts.
struct TimePrediction {
  double removal_cpu_s = 0, run_cpu_s = 0;
};
TimePrediction predict_time(const RemovalWork& work, double motion_cpu_s);

// The prediction for a job, as plan.json's "time" holds it: the counts, the costs, removal_cpu_s and run_cpu_s
// (null, with a reason, for what the model does not cover: the vdb method, an N-buffer field, a stock that is not a
// box or mesh). motions: the run's (sim/plan_motion.hpp, at the feeds the run will use); a reference job's plan
// computes that job's own reference motion.
nlohmann::json plan_time(const core::Job& job, const PlannedMotions& motions,
                         core::Progress& progress = core::no_progress());

}  // namespace vmsim::sim
