#pragma once
// `mpirun -np N vmsim run JOB`: the stock split into N tiles, one per rank (app/run_pipeline.hpp's Tile: a band of
// each dexel grid's rows, or of the needle list). Every rank runs the motion itself (deterministic: the same bits
// on every rank), cuts its tile with the sweeps that reach it, and the tiles are gathered to rank 0, which then
// holds the very field a one-process run leaves and writes the same outputs; or, with --tiles-out, each rank
// writes its tile's height grids as X3P and rank 0 a manifest (tiles.json) and report.json.
//
// Why rows: rows are DexelGrid's unit of storage (contiguous in-place intervals, one overflow table per row) and of
// parallel work, so a tile is a window of rows of the one lattice (removal::DexelGrid::v_first) and no ray is
// split; a z-map's rows run along x, so its tiles are bands in y. A three-axis finishing program made of passes at
// constant y (the plane-cylinder part) then gives each rank its own passes: few sweeps reach two tiles.
#include "core/timing.hpp"
#include "sim/pipeline.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::app {

// The tile this process holds: rank of size under MPI, the whole stock otherwise.
removal::Tile process_tile();

// Gathers the tiles of a field (collective over every rank): rank 0 gets the whole field, bit-identical to a
// one-process run's; the other ranks get nullopt. Throws core::Error when the field is too large for one
// message (MPI counts are int: use --tiles-out).
std::optional<sim::Field> gather_field(const sim::Field& tile);

// Figures of one rank's tile, gathered to rank 0 for report.json (every rank calls it; rank 0 gets all ranks').
struct TileFigures {
  double rows = 0;            // rows of the first grid (needles for N-buffer)
  double rays = 0;            // rays of the tile
  double sweeps = 0;          // sweeps that reach the tile
  double memory_bytes = 0;    // the tile's field
  double peak_rss_bytes = 0;  // the process's peak resident memory so far (VmHWM)
  double removal_s = 0;       // wall time of the tile's removal
  double removal_cpu_s = 0;   // CPU time of the tile's removal (every thread of the process)
  double cpu_s = 0;           // CPU time of the process so far (motion, stock, removal, reference)
};
std::vector<TileFigures> gather_tile_figures(const TileFigures& mine);

// --tiles-out: this rank's tile as DIR/tiles/surface_RRRR.x3p (and deviation_RRRR.x3p against the reference's
// tile when there is one); returns the manifest entry of this tile. Grid fields only (z-map, tri-dexel).
struct TileFiles {
  std::string surface, deviation;  // relative to DIR
  int first_row = 0, rows = 0, nx = 0;
  double x0_mm = 0, y0_mm = 0, x1_mm = 0, y1_mm = 0;
};
TileFiles write_tile(const std::filesystem::path& dir, const std::string& job_name, const sim::Field& field,
                     const sim::Field* reference);
// Rank 0: the manifest (every tile's files and x/y ranges, the grid spacing), written after every rank has
// written its tile (collective over every rank).
void write_tile_manifest(const std::filesystem::path& dir, const std::string& job_name, const sim::Field& field,
                         const TileFiles& mine);

// A barrier that sleeps (1 ms polls of MPI_Ibarrier) instead of spinning: a rank that finished its tile early, or
// waits while rank 0 writes the outputs, leaves its core to the others (oversubscribed or loaded machines).
// A watchdog bounds the wait (watchdog_seconds(): --watchdog-s, VMSIM_WATCHDOG_S, default 3600 s): when a rank has not
// arrived by then (stopped with kill -STOP, stuck on a stalled file system), every waiting rank throws core::Error
// naming STAGE, and rank 0's names the ranks that never arrived; the error ends every rank (mpi_abort_all) instead of
// hanging the job.
void quiet_barrier(const char* stage = "the ranks' meeting point");

using core::peak_rss_bytes;  // core/timing.hpp
using core::process_cpu_s;

}  // namespace vmsim::app
