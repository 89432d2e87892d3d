#pragma once
// vmsim run --plan JOB: a dry run. The motion is computed (it is cheap and gives the exact sample and sweep counts);
// the stock is not made. Prints, and writes as DIR/plan.json with --out, the memory model of the run: dexel counts
// and bytes of the field, its copies, the motion and its signals, the sweeps, the surfaces and meshes, for one
// process and per rank of a tiled run (--ranks N, or the MPI world size), and advice for a memory per rank. The
// model is sim/memory_plan.hpp's.
#include "app/commands.hpp"
#include "core/job.hpp"

namespace vmsim::app {

int run_plan(const core::Job& job, const RunArgs& args);

}  // namespace vmsim::app
