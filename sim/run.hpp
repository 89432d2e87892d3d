#pragma once
// A whole run of a job, as a library call: the stock, the motion through the job's chain, the sweeps cut from the
// stock, the reference, and what is read back from them (height grids or needles, the deviation, the marks, the
// part mesh, the drive signals) with every figure report.json holds. `vmsim run` writes these results to files and
// draws them; the Python module hands them over as arrays.
//
// Two stages, so that a tiled run under MPI can gather the tiles between them (app/tiled_run.hpp): cut_job (each
// process cuts its share of the rays) and finish_run (on the whole field). run_job is both, on one process.
#include "core/height_grid.hpp"
#include "core/job.hpp"
#include "core/mesh.hpp"
#include "core/progress.hpp"
#include "metrology/marks.hpp"
#include "removal/fields.hpp"
#include "removal/track.hpp"
#include "removal/vdb_part.hpp"
#include "sim/pipeline.hpp"
#include "sim/signals.hpp"
#include "sim/tools.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <optional>
#include <vector>

namespace vmsim::sim {

struct RunOptions {
  double feed_scale = 1.0;  // multiplies every programmed feed (refused with a gain schedule: its setpoints differ)
  removal::Tile tile;       // this process's share of the stock's rays (a tiled run); the whole stock by default
};

// The stock cut by the job's motion, and the reference, before any surface is read back.
struct Cut {
  Field field;
  Motion motion;
  removal::PoseTrack track;
  removal::TrackSweeps sweeps;
  double track_tolerance_mm = 0;
  std::size_t sweeps_in_tile = 0;  // sweeps that reach this process's tile (all of them for a whole field)
  Reference reference;
  // A job with several tools on a whole z-map or tri-dexel field: which tool last cut each node (tools.png).
  std::optional<ToolMap> tool_map;
  nlohmann::json timings = nlohmann::json::object();  // motion's, and stock, removal, removal_cpu, reference (s)
};

// Throws core::Error for a job that cannot run (its messages name the job file and key).
Cut cut_job(const core::Job& job, const RunOptions& options = {}, core::Progress& progress = core::no_progress());

// The level-set part of a run (method "vdb", or a tri-dexel field converted to a level set): its mesh and figures.
struct LevelSetPart {
  removal::VdbPart part;
  core::TriangleMesh mesh;  // watertight, manifold; point data "deviation_mm" against the reference's level set
  nlohmann::json figures;   // voxel_mm, mesh_triangles, mesh_vertices, mesh_adaptivity, volume_mm3, ...
};

struct RunResult {
  Cut cut;
  // Grid fields (z-map, tri-dexel, level set): heights on the z-map's nodes (mm), the reference's, and the signed
  // deviation surface - reference (negative: overcut) along the reference's normal (metrology::normal_deviation),
  // and the same vertically. The last three when the job has a reference.
  std::optional<core::HeightGrid> surface, reference_surface, deviation, deviation_vertical;
  // N-buffer fields: per needle, the surface's offset from its nominal point along its normal, the reference's
  // (NaN without a reference or where a needle is empty), and their difference.
  Eigen::VectorXd needle_offset_mm, needle_reference_mm, needle_deviation_mm;
  std::vector<metrology::Mark> marks;  // deeper than 1 um along the normal, deepest first
  // A z-map's part as a closed mesh with its deviation per vertex (removal::heightfield_mesh): made on request
  // (grid_part_mesh; the outputs when they write it, the Python module's Result.mesh), not by the run (issue 21: at
  // 0.025 mm it is 10 M triangles that a run's default outputs do not write). part_mesh_triangles: its size, -1 for
  // other fields. A level set's mesh is in level_set.
  std::optional<core::TriangleMesh> part_mesh;
  Eigen::Index part_mesh_triangles = -1;
  std::optional<LevelSetPart> level_set;
  std::optional<BinnedSignals> signals;  // when the drives ran
  // Every figure of report.json except the files written and the time spent writing and drawing.
  nlohmann::json report;
};

// The surfaces, marks and report of a cut (the run's options are in it already: the feeds, the tile).
RunResult finish_run(const core::Job& job, Cut cut, core::Progress& progress = core::no_progress());

// The z-map part's mesh (r.part_mesh when made already). r must hold a grid surface.
core::TriangleMesh grid_part_mesh(const RunResult& r);

// cut_job then finish_run, on one process.
RunResult run_job(const core::Job& job, const RunOptions& options = {}, core::Progress& progress = core::no_progress());

}  // namespace vmsim::sim
