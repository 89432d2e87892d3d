#pragma once
// The dexel kernels and the track's merge as they were before issue 21's faster paths (per sweep and ray: the
// vectorised prefilter, a scalar compaction, the exact bounds; the general ray test on every ray whose material meets
// the sweep's extent; every needle against every sweep whose box meets its block's), kept as the reference the fast
// kernels in cut.cpp and fields.cpp must match bit for bit: tests/removal/cut_equivalence_test.cpp, and
// bench/removal_bench.cpp times both in one run. Not for production use: cut() gives the same intervals faster.
#include "removal/cut.hpp"
#include "removal/dexel_grid.hpp"
#include "removal/track.hpp"

#include <vector>

namespace vmsim::removal {

CutStats cut_reference(DexelGrid& grid, const std::vector<SweptTool>& sweeps);
CutStats cut_reference(NeedleSet& needles, const std::vector<SweptTool>& sweeps);
// sweeps_from_track as it was (the same sweeps, bit for bit, with more work per pose).
TrackSweeps sweeps_from_track_reference(const Tool& tool, const PoseTrack& track, const TrackOptions& options = {});

}  // namespace vmsim::removal
