#pragma once
// Material removal on dexel grids: every swept tool volume subtracted from every ray it crosses.
#include "removal/dexel_grid.hpp"
#include "removal/swept_tool.hpp"

#include <vector>

namespace vmsim::removal {

struct CutStats {
  std::size_t ray_tests = 0;   // ray-tool evaluations
  std::size_t cuts = 0;        // evaluations that removed material or touched an interval
};

// Subtracts each swept volume from the grid. Rows are distributed over OpenMP threads in blocks; every ray sees
// the sweeps in the same order, and subtraction does not depend on order anyway: the result is bit-identical
// for any thread count.
CutStats cut(DexelGrid& grid, const std::vector<SweptTool>& sweeps);

}  // namespace vmsim::removal
