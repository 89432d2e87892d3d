#pragma once
// cut_field (sim/pipeline.hpp) with progress: a whole dexel field is cut in batches of consecutive sweeps (the same
// intervals bit for bit: each ray sees the sweeps in the same order) and progress->update says the sweeps done times
// the grids done, from which the terminal draws the time left. Its own header so that adding it rebuilds two files.
#include "sim/pipeline.hpp"
#include "sim/tools.hpp"

namespace vmsim::sim {

std::size_t cut_field(Field& f, const std::vector<removal::SweptTool>& sweeps, core::Progress* progress);

// The same cut (bit for bit), run by run of sweeps.runs, and the map of which tool last lowered each node's top
// (comparing the z grid's tops before and after each run). Throws core::Error for a field without a z grid (needles,
// level set), a tile of a tiled run, runs that do not cover the sweeps, or more than 254 tools.
std::size_t cut_field(Field& f, const removal::TrackSweeps& sweeps, core::Progress* progress, ToolMap& map);

}  // namespace vmsim::sim
