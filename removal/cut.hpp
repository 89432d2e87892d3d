#pragma once
// Material removal on dexel grids: every swept tool volume subtracted from every ray it crosses.
#include "core/progress.hpp"
#include "removal/dexel_grid.hpp"
#include "removal/swept_tool.hpp"

#include <vector>

namespace vmsim::removal {

// What a cut() did. An evaluation is a (ray, sweep) pair the kernel looks at: for a ball-end sweep along the rays,
// every ray of the sweep's shadow (the rays within R of the centre's path); for other sweeps, every ray whose material
// meets the sweep's extent along it.
struct CutStats {
  std::size_t ray_tests = 0;  // evaluations
  std::size_t cuts = 0;       // evaluations that removed material or touched an interval
  // Evaluations that changed nothing, by what settled them (ball-end sweeps along the rays):
  std::size_t tile_skipped = 0;       // a tile's bound (the sweep's lowest point over a tile of rays above its top)
  std::size_t bound_skipped = 0;      // the ray's square-root-free bound
  std::size_t exact_nothing = 0;      // the exact cut
  std::size_t order_free_blocks = 0;  // runs of sweeps through a block of rows cut lowest sweep first (cut.cpp)
  std::size_t replayed = 0;           // rays of those that had to be redone in program order
  // (sweep, block of rows) pairs a chunk's bound settled before any of their evaluations (not in ray_tests)
  std::size_t chunk_skipped = 0;
};

// Subtracts each swept volume from the grid. Rows are distributed over OpenMP threads in blocks; every ray sees
// the sweeps in the same order, and subtraction does not depend on order anyway: the result is bit-identical
// for any thread count.
CutStats cut(DexelGrid& grid, const std::vector<SweptTool>& sweeps);
// The same cut, reporting its progress to `progress` (when not null) as it goes: progress->update(done + the sweeps
// times the share of the grid's rows cut so far), from the calling thread between bands of rows. One call with all of
// a job's sweeps, not batches of them: the kernel takes each block of rows' sweeps lowest first, which a batch can
// only do within itself (flower_mold: the cut's CPU 1.5x in batches of 4096 sweeps, bench/README.md).
CutStats cut(DexelGrid& grid, const std::vector<SweptTool>& sweeps, core::Progress* progress, double done);

// The rays [i0, i1] x [j0, j1] (the grid's own row indices) whose lines can meet a sweep's bounding box: the only
// rays cut() lets the sweep touch, and the box's extent [w0, w1] along them (mm from the grid's origin). Empty when
// the sweep misses the grid (or the grid's window of rows).
struct Footprint {
  int i0 = 0, i1 = -1, j0 = 0, j1 = -1;
  double w0 = 0, w1 = 0;
  bool empty() const { return i0 > i1 || j0 > j1; }
};
Footprint footprint(const DexelGrid& grid, const SweptTool& sweep);

// The sweeps whose footprint on the grid is not empty, in their order: cutting a grid (or a window of rows of a
// larger grid, a tile) with these alone leaves every ray bit-identical to cutting it with all of them, since each
// ray sees the same sweeps in the same order.
std::vector<SweptTool> sweeps_reaching(const DexelGrid& grid, const std::vector<SweptTool>& sweeps);

}  // namespace vmsim::removal
