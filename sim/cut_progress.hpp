#pragma once
// cut_field (sim/pipeline.hpp) with progress: a whole dexel field is cut in batches of consecutive sweeps (the same
// intervals bit for bit: each ray sees the sweeps in the same order) and progress->update says the sweeps done times
// the grids done, from which the terminal draws the time left. Its own header so that adding it rebuilds two files.
#include "sim/pipeline.hpp"

namespace vmsim::sim {

std::size_t cut_field(Field& f, const std::vector<removal::SweptTool>& sweeps, core::Progress* progress);

}  // namespace vmsim::sim
