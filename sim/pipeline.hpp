#pragma once
// vmsim run's chain as callable stages: job -> motion -> pose track -> sweeps -> field (stock cut by the sweeps) ->
// surfaces. `vmsim run` (app/cmd_run.cpp) calls them once per job and writes the outputs; a tiled run under MPI
// can call the same stages.
#include "core/progress.hpp"
#include "motion/contour.hpp"
#include "core/height_grid.hpp"
#include "motion/interp.hpp"
#include "core/job.hpp"
#include "core/mesh.hpp"
#include "program/program.hpp"
#include "drives/simulate.hpp"
#include "removal/fields.hpp"
#include "removal/track.hpp"
#include "removal/vdb_part.hpp"
#include "sim/chain.hpp"
#include "sim/signals.hpp"

#include <nlohmann/json.hpp>

#include <optional>
#include <set>
#include <string>
#include <vector>

namespace vmsim::sim {

const char* motion_name(core::RemovalSpec::Motion m);

// One job's motion through the chain, as far as its removal needs it.
struct Motion {
  core::ToolPath program;  // tool tip, workpiece frame
  motion::InterpResult interp;
  std::optional<drives::AxisResponse> response;
  std::optional<motion::ContourError> contour;
  Eigen::VectorXd tool_length_offset_mm;  // per setpoint (sim::tool_length_offsets)
  DriveChecks drive_checks;               // the drives' findings, when they ran (sim/drive_checks.hpp)
  nlohmann::json timings = nlohmann::json::object();
  // A streamed motion (sim/motion_stream.hpp): the response and the setpoints' positions were consumed block by
  // block and released (response has no rows, setpoints.position no columns, tool_length_offset_mm is empty); the
  // figures taken from them on the way are here.
  bool streamed = false;
  std::optional<BinnedSignals> signals;                      // streamed: the signals (signals.csv)
  nlohmann::json axis_following = nlohmann::json::object();  // streamed: as sim/axis_following.hpp gives it
};

// The first stages of every motion, into m: the program read (a tool the job does not describe fails here, before any
// motion is computed) and, but for motion = "program", interpolated (m.timings: read_program, interpolate).
void read_and_interpolate(const Chain& chain, core::RemovalSpec::Motion kind, Motion& m, core::Progress& progress);

// Program -> interpolator -> drives of the chain, as far as `kind` needs (program: read only; setpoints:
// interpolated; actual: through the drives).
Motion simulate_motion(const Chain& chain, core::RemovalSpec::Motion kind, core::Progress& progress);
// The contour error of the actual tool tip against the commanded one (when the drives ran).
void add_contour_error(Motion& m, const core::Job& job);
// Tool length offset active at setpoint sample k (the last setpoint's while the axes settle after it).
double tlo_at(const Motion& m, Eigen::Index k);

// Tool-tip track (and tool axis on five-axis work) of the motion that cuts.
// The track tolerance a job cuts at: its own, or, when it gives none and a level set cuts a turning tool, voxel / 10
// (core/job.hpp: each orientation sub-step is an exact sweep the level set pays for; 3-axis tracks keep the default,
// which costs no extra sweeps there).
double track_tolerance(const core::Job& job, bool tool_turns);
// Whether a track's tool axis turns anywhere (a 5-axis track).
bool track_turns(const removal::PoseTrack& track);
removal::PoseTrack track_of(const Motion& m, const core::Job& job, core::RemovalSpec::Motion kind);
// The track of the chain's motion of `kind` alone (a stock job's, a feed reference's): the actual motion streamed
// (sim/motion_stream.hpp), the same track as track_of(simulate_motion(...)) without holding the drives' response.
removal::PoseTrack motion_track(const Chain& chain, core::RemovalSpec::Motion kind, core::Progress& progress);
// The track as the tool's swept volumes, within the job's track tolerance.
removal::TrackSweeps sweeps_of(const core::Job& job, const removal::PoseTrack& track);

// The bounding box of the stock's material: a box stock's box, a mesh stock's mesh's (the STL is read); none for a stock
// that another job leaves, or a mesh without vertices. The one derivation the field, the plans and the sweeps share.
std::optional<removal::Box> stock_box(const core::Job& job);
removal::Box mesh_box(const core::TriangleMesh& mesh);  // the mesh must have vertices

// A share of the stock's rays for one process (removal/fields.hpp): all of them in a plain run; tile `rank` of
// `ranks` in a tiled run under MPI (app/tiled_run.hpp), a band of every dexel grid's rows or of the needle list's
// blocks of removal::NeedleSet::kBlock needles.
using removal::Tile;

// The stock's dexels, or its level set (method "vdb": `kind` then only says which surfaces are read back).
struct Field {
  core::RemovalSpec::Field kind = core::RemovalSpec::Field::ZMap;
  bool vdb = false;
  removal::VdbPart part;               // vdb
  double vdb_estimate_bytes = 0;       // vdb: the level set's memory stated before the run
  double vdb_mesh_estimate_bytes = 0;  // vdb: the part mesh's
  removal::Box region;
  double spacing_mm = 0.05;
  removal::DexelGrid zmap;
  removal::TriDexel tri;
  removal::NeedleSet needles;
  std::vector<Eigen::Vector3d> needle_point, needle_normal;  // nominal points and normals (N-buffer)
  double needle_half = 1.0;
  // A tile's share: the rows of each grid (DexelGrid::v_first), the needles [needle_first, + needles.size()) of the
  // whole list (needle_point / needle_normal always hold the whole list, so rank 0 can rebuild the whole set).
  Tile tile;
  std::size_t needle_first = 0;

  std::size_t rays() const;
  std::size_t memory_bytes() const;
  std::vector<removal::DexelGrid*> grids();  // the dexel grids: z-map 1, tri-dexel 3, needles and vdb none
  std::vector<const removal::DexelGrid*> grids() const;
};

// A job's starting field: a box or mesh stock, or the part another job leaves (run here, recursively; `chain`
// catches cycles). With a tile, only the tile's rays are made and filled.
Field initial_field(const core::Job& job, core::Progress& progress, std::set<std::string>& chain,
                    const Tile& tile = {});
// The part a job leaves: its stock, cut by its own motion.
Field final_field(const core::Job& job, core::Progress& progress, std::set<std::string>& chain, const Tile& tile = {});
// Removes the sweeps from the field (in program order; the dexel kernels' results do not depend on thread count).
// A tile is cut only by the sweeps that reach it (removal::sweeps_reaching: its rays end bit-identical to the same
// rays of the whole field). Returns how many sweeps reach the field (all of them for a whole field).
std::size_t cut_field(Field& f, const std::vector<removal::SweptTool>& sweeps);

// The reference surface a job's marks are measured against ([reference] kind): its field and its description.
struct Reference {
  std::optional<Field> field;
  std::string name = "none";
};
// `start` is the field the job starts from (copied for kinds feed, stock and program); a reference job is run on
// start's tile.
Reference reference_field(const core::Job& job, const Field& start, double feed_scale, core::Progress& progress);

// Surface of a grid field (z-map, or the tri-dexel's Z grid; a level set read back on the z-map's nodes).
core::HeightGrid surface_of(const Field& f);
// Along each needle, the surface's position relative to the nominal point (mm along the normal; NaN if empty).
Eigen::VectorXd needle_offsets(const Field& f);

}  // namespace vmsim::sim
